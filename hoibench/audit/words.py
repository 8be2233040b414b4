"""Words of a caption line for the text corruptions: spans aligned with HumanML3D ``word/POS``
tokens, phrase matching, and English verb inflection (3rd person, gerund, past)."""
from __future__ import annotations

import re
from dataclasses import dataclass

from ..evaluator.text import NOT_ACTION  # the verbs that are not the action (auxiliaries, copulas)

_SPAN = re.compile(r"[A-Za-z]+(?:-[A-Za-z]+)*")
_VOWELS = re.compile(r"[aeiou]+")
#: nouns that name the person or a body part, never the object (the POS fallback skips them)
NOT_OBJECT = frozenset(
    "person people man woman human someone somebody guy girl boy lady individual subject figure character "
    "hand hands arm arms foot feet leg legs head back shoulder shoulders knee knees hip hips body finger "
    "fingers elbow elbows waist chest side front left right time step steps way place floor ground".split())
_IRREGULAR_PAST = {"put": "put", "set": "set", "sit": "sat", "hold": "held", "take": "took", "bring": "brought",
                   "throw": "threw", "catch": "caught", "swing": "swung", "stand": "stood", "get": "got",
                   "hit": "hit", "run": "ran", "go": "went", "make": "made", "lean": "leaned"}


@dataclass(frozen=True)
class Word:
    """One word of a caption: its span in the text, lower-cased form, lemma and POS."""

    start: int
    end: int
    word: str
    lemma: str
    pos: str


def split_tokens(tokens) -> list[tuple[str, str]]:
    """``word/POS`` strings -> ``(word, POS)`` pairs (POS ``X`` when a token has none)."""
    out = []
    for t in tokens:
        word, _, pos = str(t).rpartition("/")
        out.append((word, pos) if word else (str(t), "X"))
    return out


def _aligned(spans: list, tags: list[tuple[str, str]]) -> bool:
    if len(spans) != len(tags):
        return False
    return all(w == s or pos in ("NOUN", "VERB") for s, (w, pos) in zip(spans, tags))


def words(text: str, tokens=()) -> list[Word]:
    """The words of ``text`` with lemma and POS from ``tokens`` when they align with the words
    (same count, same words up to the lemmas of nouns and verbs), else from
    :func:`hoibench.text.tokens.tokens` (spaCy or the rule-based tagger), else POS ``X``."""
    matches = list(_SPAN.finditer(text))
    spans = [m.group().lower().replace("-", "") for m in matches]
    tags = split_tokens(tokens)
    if not _aligned(spans, tags):
        from ..text.tokens import tokens as tag
        tags = split_tokens(tag(text))
        if not _aligned(spans, tags):
            tags = [(s, "X") for s in spans]
    return [Word(m.start(), m.end(), s, w, pos) for m, s, (w, pos) in zip(matches, spans, tags)]


def hml(ws: list[Word]) -> tuple[str, ...]:
    """HumanML3D tokens of ``ws``."""
    return tuple(f"{w.lemma}/{w.pos}" for w in ws)


def same_word(w: Word, lemma: str) -> bool:
    """Whether ``w`` is ``lemma`` (itself, its lemma, or a plural ``-s``/``-es``)."""
    return lemma in (w.word, w.lemma) or w.word in (lemma + "s", lemma + "es")


def find_phrase(ws: list[Word], phrase: tuple[str, ...]) -> list[int]:
    """Start indices of the non-overlapping occurrences of ``phrase`` (lemmas) in ``ws``."""
    out, i, m = [], 0, len(phrase)
    while m and i + m <= len(ws):
        if all(same_word(ws[i + k], phrase[k]) for k in range(m)):
            out.append(i)
            i += m
        else:
            i += 1
    return out


def _cvc(lemma: str) -> bool:
    """One vowel group ending consonant-vowel-consonant (not w, x, y): ``sit`` -> ``sitting``."""
    return (len(_VOWELS.findall(lemma)) == 1 and len(lemma) >= 3 and lemma[-1] not in "aeiouwxy"
            and lemma[-2] in "aeiou" and lemma[-3] not in "aeiou")


def inflect(lemma: str, form: str) -> str:
    """``lemma`` in ``form``: ``base``, ``s`` (3rd person), ``ing`` or ``ed`` (past)."""
    if form == "s":
        if lemma.endswith(("s", "sh", "ch", "x", "z", "o")):
            return lemma + "es"
        return lemma[:-1] + "ies" if lemma.endswith("y") and lemma[-2:-1] not in "aeiou" else lemma + "s"
    if form == "ing":
        if lemma.endswith("ie"):
            return lemma[:-2] + "ying"
        if lemma.endswith("e") and not lemma.endswith(("ee", "ye", "oe")):
            return lemma[:-1] + "ing"
        return lemma + lemma[-1] + "ing" if _cvc(lemma) else lemma + "ing"
    if form == "ed":
        if lemma in _IRREGULAR_PAST:
            return _IRREGULAR_PAST[lemma]
        if lemma.endswith("e"):
            return lemma + "d"
        if lemma.endswith("y") and lemma[-2:-1] not in "aeiou":
            return lemma[:-1] + "ied"
        return lemma + lemma[-1] + "ed" if _cvc(lemma) else lemma + "ed"
    return lemma


def form_of(word: str, lemma: str) -> str:
    """The form (see :func:`inflect`) ``word`` has as an inflection of ``lemma``."""
    for form in ("base", "s", "ing", "ed"):
        if word == inflect(lemma, form):
            return form
    if word.endswith("ing"):
        return "ing"
    if word.endswith("ed"):
        return "ed"
    return "s" if word.endswith("s") and not word.endswith("ss") else "base"


def replace_span(text: str, start: int, end: int, new: str) -> str:
    """``text`` with ``text[start:end]`` replaced by ``new``, capitalised when the old was."""
    if text[start:start + 1].isupper():
        new = new[:1].upper() + new[1:]
    return text[:start] + new + text[end:]
