"""HumanML3D ``tokens`` for free text: ``word/POS`` pairs as HumanML3D's ``text_process.py``.

HumanML3D lower-cases the caption, drops non-alphabetic tokens, lemmatises nouns and verbs
(except "left") and tags with spaCy's universal POS (``a/DET man/NOUN kick/VERB``).

:func:`tokens` uses spaCy when an English pipeline (``en_core_web_sm``) is installed, else a
documented rule-based fallback: a closed-class lexicon (determiners, pronouns, adpositions,
conjunctions, auxiliaries, common adverbs/adjectives of motion text) plus suffix rules for
verbs (-s/-es/-ed/-ing stripped to a lemma when the word is a known motion verb or ends in
-ing/-ed) and NOUN as the default. :func:`backend` says which one ran; exports record it.
"""
from __future__ import annotations

import re
from functools import lru_cache

_CLOSED = {
    "DET": "a an the this that these those each every some any another its his her their".split(),
    "PRON": "he she it they him them someone somebody person's himself herself itself something one".split(),
    "ADP": "with on onto in into from to at by over under up down off across around behind of "
           "towards toward through along near beside above below out".split(),
    "CCONJ": "and or but".split(),
    "SCONJ": "while as before after until when".split(),
    "AUX": "is are was were be being been has have had does do did".split(),
    "ADV": "then slowly quickly back forward forwards backward backwards again away together "
           "briefly carefully".split(),
    "ADJ": "left right both small large big heavy light wooden black white round".split(),
    "NUM": "one two three four five".split(),
}
_POS = {w: pos for pos, words in _CLOSED.items() for w in words}
_MOTION_VERBS = set("lift carry put push pull sit kick hold pick place move walk grab raise lower "
                    "drag hug touch lean stand turn step throw catch rotate adjust play type set "
                    "bring take drop slide roll swing bend reach".split())
_WORD = re.compile(r"[a-z]+")


def _lemma_verb(word: str) -> str | None:
    for suffix, repl in (("ing", ""), ("ies", "y"), ("es", ""), ("ed", ""), ("s", "")):
        if word.endswith(suffix):
            stem = word[: -len(suffix)] + repl
            for cand in (stem, stem + "e", stem[:-1] if len(stem) > 2 and stem[-1] == stem[-2] else stem):
                if cand in _MOTION_VERBS:
                    return cand
    return word if word in _MOTION_VERBS else None


def _fallback(text: str) -> list[str]:
    out = []
    for word in _WORD.findall(text.lower().replace("-", "")):
        if word in _POS:
            out.append(f"{word}/{_POS[word]}")
        elif (lemma := _lemma_verb(word)) is not None:
            out.append(f"{lemma}/VERB")
        else:
            noun = word[:-1] if word.endswith("s") and not word.endswith("ss") and len(word) > 3 else word
            out.append(f"{noun}/NOUN")
    return out


@lru_cache(maxsize=1)
def _spacy():
    try:
        import spacy
        return spacy.load("en_core_web_sm")
    except Exception:  # not installed, or no English pipeline
        return None


def backend() -> str:
    return "spacy:en_core_web_sm" if _spacy() is not None else "hoibench-rules-1.0"


def tokens(text: str) -> list[str]:
    """``word/POS`` tokens of ``text`` in HumanML3D's convention."""
    nlp = _spacy()
    if nlp is None:
        return _fallback(text)
    out = []
    for tok in nlp(text.lower().replace("-", "")):
        word = tok.text
        if not word.isalpha():
            continue
        if tok.pos_ in ("NOUN", "VERB") and word != "left":
            word = tok.lemma_
        out.append(f"{word}/{tok.pos_}")
    return out


def humanml3d_line(caption: str, start: float = 0.0, end: float = 0.0, toks: list[str] | None = None) -> str:
    """``caption#tokens#start#end`` (one line of a HumanML3D text file)."""
    if "#" in caption or "\n" in caption:
        raise ValueError(f"caption: must not contain '#' or a newline: {caption!r}")
    return f"{caption}#{' '.join(toks if toks is not None else tokens(caption))}#{start}#{end}"
