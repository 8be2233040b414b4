"""Text corruptions of a split's captions (clip id -> caption lines,
:class:`hoibench.evaluator.text.Caption`). Each family corrupts every line of a fraction of
the clips: ``severity`` = that fraction, the clips chosen by
:func:`hoibench.audit.streams.selected` (nested across severities); the other clips' lines
are returned unchanged. Per-clip choices draw from the stream of (seed, family,
``severity_index``, clip). An edited line's ``tokens`` are the line's ``word/POS`` tokens
(its own when they align with its words, else re-tagged) with the edit applied."""
from __future__ import annotations

import dataclasses
from typing import Mapping, Sequence

from ..evaluator.text import Caption
from .checks import Context, check_context, check_severity
from .streams import check_seed, clip_stream, selected
from .words import NOT_ACTION, NOT_OBJECT, Word, find_phrase, form_of, hml, inflect, replace_span, split_tokens, words

Captions = Mapping[str, Sequence[Caption]]


def _check(captions, severity, seed, ctx) -> float:
    s = check_severity(severity, 0.0, 1.0, " (fraction of clips)")
    check_seed(seed)
    check_context(ctx)
    if not isinstance(captions, Mapping):
        raise ValueError(f"captions: expected a mapping of clip id -> caption lines, got {type(captions).__name__}")
    for cid, lines in captions.items():
        if not isinstance(cid, str) or isinstance(lines, (str, bytes)) or \
                not all(isinstance(c, Caption) for c in lines):
            raise ValueError(f"captions[{cid!r}]: expected a sequence of Caption lines")
    return s


def _copy(captions: Captions) -> dict[str, list[Caption]]:
    return {cid: list(lines) for cid, lines in captions.items()}


def caption_swap(captions: Captions, severity: float, seed: int, ctx: Context,
                 severity_index: int = 0) -> dict[str, list[Caption]]:
    """The selected clips (at least two when ``severity > 0``) pass their lines round a cycle:
    the i-th selected clip gets the lines of the (i+1)-th (mod their number), so no selected
    clip keeps its own and the multiset of captions is kept. No per-clip randomness."""
    s = _check(captions, severity, seed, ctx)
    out = _copy(captions)
    chosen = selected(captions, s, seed, "caption_swap", minimum=2)
    for i, cid in enumerate(chosen):
        out[cid] = list(captions[chosen[(i + 1) % len(chosen)]])
    return out


def _edit(c: Caption, ws: list[Word], at: list[int], length: int, new_words: list[str],
          new_tokens: tuple[str, ...]) -> Caption:
    """Replace the ``length`` words from each index of ``at`` by ``new_words`` (tokens by
    ``new_tokens``); an article ``a``/``an`` just before follows the new first word."""
    text, toks = c.text, list(hml(ws))
    for i in reversed(at):
        text = replace_span(text, ws[i].start, ws[i + length - 1].end, " ".join(new_words))
        toks[i:i + length] = new_tokens
        if i > 0 and ws[i - 1].word in ("a", "an"):
            article = "an" if new_words[0][:1] in tuple("aeiou") else "a"
            text = replace_span(text, ws[i - 1].start, ws[i - 1].end, article)
            toks[i - 1] = f"{article}/{ws[i - 1].pos}"
    return dataclasses.replace(c, text=text, tokens=tuple(toks))


def _noun_line(c: Caption, own: tuple, others: tuple, phrase: tuple[str, ...]) -> Caption:
    """Replace the object's noun phrase in one line (see :func:`noun_swap`)."""
    ws = words(c.text, c.tokens)
    lemmas = [w for w, _ in split_tokens(phrase)]
    for cands in (own, others):
        for p in sorted(cands, key=len, reverse=True):
            at = find_phrase(ws, tuple(w for w, _ in split_tokens(p)))
            if at:
                return _edit(c, ws, at, len(p), lemmas, phrase)
    for i, w in enumerate(ws):
        if w.pos == "NOUN" and w.word not in NOT_OBJECT and w.lemma not in NOT_OBJECT:
            return _edit(c, ws, [i], 1, lemmas, phrase)
    return c


def noun_swap(captions: Captions, severity: float, seed: int, ctx: Context,
              severity_index: int = 0) -> dict[str, list[Caption]]:
    """The object's noun replaced by another object's: a selected clip draws an object of
    another category from ``ctx.objects`` (another name when every object shares its category)
    and one of its noun phrases (``ctx.nouns``); in every line, the occurrences of the clip's
    own object's longest matching phrase (``ctx.clip_objects``), else of any listed object's,
    else the first noun tagged NOUN that names neither the person nor a body part
    (:data:`~hoibench.audit.words.NOT_OBJECT`), are replaced by it. A line with none of these
    is kept."""
    s = _check(captions, severity, seed, ctx)
    out = _copy(captions)
    chosen = selected(captions, s, seed, "noun_swap")
    pool = sorted(set(ctx.objects))
    if chosen and len(pool) < 2:
        raise ValueError(f"ctx: objects must name at least two objects to swap between, got {pool}")
    cat = {o: ctx.object_categories.get(o, o) for o in pool}
    for cid in chosen:
        own = ctx.clip_objects.get(cid, "")
        cands = [o for o in pool if cat[o] != ctx.object_categories.get(own, own)] or [o for o in pool if o != own]
        rng = clip_stream(seed, "noun_swap", severity_index, cid)
        new = cands[int(rng.integers(len(cands)))]
        phrases = ctx.nouns(new)
        phrase = phrases[int(rng.integers(len(phrases)))]
        mine = ctx.nouns(own) if own else ()
        others = tuple(p for o in sorted(set(pool) | set(ctx.object_nouns)) if o != own for p in ctx.nouns(o))
        out[cid] = [_noun_line(c, mine, others, phrase) for c in captions[cid]]
    return out


def _main_verb(ws: list[Word], verbs: tuple[str, ...]) -> int | None:
    """Index of the first word tagged VERB (not an auxiliary), else of the first word that is an
    inflection of one of ``verbs``."""
    for i, w in enumerate(ws):
        if w.pos == "VERB" and w.lemma not in NOT_ACTION:
            return i
    for i, w in enumerate(ws):
        for v in verbs:
            if w.word in {inflect(v, f) for f in ("base", "s", "ing", "ed")}:
                return i
    return None


def _lemma_of(w: Word, verbs: tuple[str, ...]) -> str:
    if w.pos == "VERB":
        return w.lemma
    return next(v for v in verbs if w.word in {inflect(v, f) for f in ("base", "s", "ing", "ed")})


def verb_swap(captions: Captions, severity: float, seed: int, ctx: Context,
              severity_index: int = 0) -> dict[str, list[Caption]]:
    """The main verb of every line of a selected clip (:func:`_main_verb`) replaced by a verb
    drawn from ``ctx.verbs`` less its own lemma, inflected as the old word was (``-s``,
    ``-ing``, past, base). A line without a verb is kept."""
    s = _check(captions, severity, seed, ctx)
    out = _copy(captions)
    chosen = selected(captions, s, seed, "verb_swap")
    verbs = tuple(sorted(set(ctx.verbs)))
    if chosen and len(verbs) < 2:
        raise ValueError(f"ctx: verbs must name at least two verbs to swap between, got {list(verbs)}")
    for cid in chosen:
        rng = clip_stream(seed, "verb_swap", severity_index, cid)
        lines = []
        for c in captions[cid]:
            ws = words(c.text, c.tokens)
            i = _main_verb(ws, verbs)
            if i is None:
                lines.append(c)
                continue
            old = _lemma_of(ws[i], verbs)
            others = [v for v in verbs if v != old]
            new = others[int(rng.integers(len(others)))]
            lines.append(_edit(c, ws, [i], 1, [inflect(new, form_of(ws[i].word, old))], (f"{new}/VERB",)))
        out[cid] = lines
    return out


def split_verbs(captions: Captions) -> tuple[str, ...]:
    """The main-verb lemmas of a split's lines (the first word tagged VERB, not an auxiliary),
    sorted: the pool :func:`verb_swap` draws from."""
    found = set()
    for lines in captions.values():
        for c in lines:
            ws = words(c.text, c.tokens)
            i = _main_verb(ws, ())
            if i is not None:
                found.add(ws[i].lemma)
    return tuple(sorted(found))

