"""Text: contact-aware annotation of a store (spec, timelines, captions) and token tagging."""
