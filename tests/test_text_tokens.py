"""HumanML3D token strings for free text (rule-based fallback when spaCy is absent)."""
from __future__ import annotations

import pytest

from hoibench.text import tokens as text_tokens


def test_fallback_tags_and_lemmatises_like_humanml3d():
    toks = text_tokens._fallback("A person is lifting the small box with both hands, then puts it down.")
    assert toks == ["a/DET", "person/NOUN", "is/AUX", "lift/VERB", "the/DET", "small/ADJ", "box/NOUN",
                    "with/ADP", "both/ADJ", "hand/NOUN", "then/ADV", "put/VERB", "it/PRON", "down/ADP"]


def test_line_format_and_bad_caption():
    line = text_tokens.humanml3d_line("someone kicks the ball", 0.5, 2.0, ["someone/PRON", "kick/VERB", "the/DET", "ball/NOUN"])
    assert line.split("#") == ["someone kicks the ball", "someone/PRON kick/VERB the/DET ball/NOUN", "0.5", "2.0"]
    with pytest.raises(ValueError, match="caption"):
        text_tokens.humanml3d_line("a#b")
    assert text_tokens.backend() in ("hoibench-rules-1.0", "spacy:en_core_web_sm")
