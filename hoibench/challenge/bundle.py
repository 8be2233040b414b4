"""``hoibench challenge bundle``: a Codabench competition bundle (YAML version 2, as
Codabench's ``competitions/unpackers/v2.py`` reads it; docs/hosting.md names the version).

Layout of ``bundle.zip``::

    competition.yaml          version 2: title, description, docker_image, terms, pages,
                              tasks (scoring program + reference data), phases, leaderboards
    overview.md evaluation.md data.md terms.md
    logo.png
    scoring_program.zip       metadata.yaml (command) + score.py (-> hoibench.challenge.scoring)
    reference_data.zip        the hidden store split + evaluator + challenge.json (.reference)
    docker/Dockerfile         the image the competition names: hoibench CPU-only

Phases map to the protocol's split (every phase scores the hidden test split; they differ
in dates and submission limits: ``dev`` 5 a day, ``test`` 2 in all by default). Their dates
(:func:`phase_dates`) run from ``start`` (default: the day the bundle is built) to ``end``
(default: :data:`PHASE_DAYS` days per phase), split into consecutive equal parts. The
leaderboard has one column per metric of the track (sorting ``asc`` for lower-is-better,
``desc`` otherwise), the primary column first, plus the hidden ``evaluator_id8`` and
``protocol_sha8`` columns.
"""
from __future__ import annotations

import io
import json
import tempfile
import zipfile
from datetime import date, timedelta
from pathlib import Path

from .. import __version__

#: the zip members every bundle has, and the keys Codabench's v2 unpacker requires
REQUIRED_FILES = ("competition.yaml", "terms.md", "scoring_program.zip", "reference_data.zip", "logo.png")
REQUIRED_KEYS = ("version", "title", "terms", "pages", "tasks", "phases", "leaderboards")
PHASE_LIMITS = {"dev": {"max_submissions_per_day": 5, "max_submissions": 100},
                "test": {"max_submissions_per_day": 1, "max_submissions": 2}}
#: the days of one phase when the bundle names no end date
PHASE_DAYS = 90
SCORING_COMMAND = "python3 /app/program/score.py /app/input /app/output"
#: the largest bundle :func:`check_bundle` reads
MAX_BUNDLE_BYTES = 64 * 1024 ** 3
#: Codabench column titles and keys are at most 36 characters
MAX_KEY = 36


def leaderboard_columns(track: str) -> list[dict]:
    """Codabench columns for ``track``'s leaderboard metrics (plus the hidden id columns)."""
    from ..metrics import METRICS
    from ..publish.leaderboard import table_columns, title
    cols = []
    for i, key in enumerate(table_columns(track)):
        info = METRICS.get(key)
        sorting = "desc" if (info is not None and info.higher_is_better) else "asc"
        cols.append({"title": title(key)[:MAX_KEY], "key": key[:MAX_KEY], "index": i, "sorting": sorting,
                     "precision": 4})
    n = len(cols)
    cols += [{"title": "evaluator id (8 hex as int)", "key": "evaluator_id8", "index": n, "sorting": "asc",
              "hidden": True, "precision": 0},
             {"title": "protocol sha (8 hex as int)", "key": "protocol_sha8", "index": n + 1, "sorting": "asc",
              "hidden": True, "precision": 0}]
    return cols


def _yaml(obj) -> str:
    import yaml
    return yaml.safe_dump(obj, sort_keys=False, allow_unicode=True, default_flow_style=False)


def phase_dates(n: int, start: date, end: date | None = None) -> list[tuple[date, date]]:
    """First and last day (inclusive) of ``n`` consecutive phases from ``start`` to ``end``:
    ``end - start + 1`` days split into ``n`` parts of ``(end - start + 1) // n`` days, the last
    part taking the remainder. Default ``end``: ``PHASE_DAYS`` days per phase."""
    if end is None:
        end = start + timedelta(days=PHASE_DAYS * n - 1)
    if end < start:
        raise ValueError(f"--end {end.isoformat()}: before --start {start.isoformat()}")
    days = (end - start).days + 1
    if days < n:
        raise ValueError(f"--end {end.isoformat()}: {n} phases need at least {n} days from --start "
                         f"{start.isoformat()}, got {days}")
    length = days // n
    out = [(start + timedelta(days=length * i), start + timedelta(days=length * (i + 1) - 1)) for i in range(n)]
    out[-1] = (out[-1][0], end)
    return out


def phase_warnings(phases: list[dict], today: date) -> list[str]:
    """Phases of a ``competition.yaml`` that will take no submissions: without a start date,
    ending before they start, or ended before ``today``."""
    out = []
    for p in phases:
        name, start, end = p.get("name"), p.get("start"), p.get("end")
        try:
            start = date.fromisoformat(str(start)) if start is not None else None
            end = date.fromisoformat(str(end)) if end is not None else None
        except ValueError:
            continue                      # a problem, reported by check_bundle
        if start is None:
            out.append(f"phase {name}: no start date: it never starts")
        elif end is not None and end < start:
            out.append(f"phase {name}: ends ({end.isoformat()}) before it starts ({start.isoformat()}): "
                       f"it never starts")
        elif end is not None and end < today:
            out.append(f"phase {name}: ended on {end.isoformat()} (today is {today.isoformat()}); set new dates "
                       f"with hoibench challenge bundle --start DATE --end DATE")
    return out


def competition_yaml(title: str, track: str, phases: list[str], docker_image: str, start: date,
                     end: date | None = None) -> dict:
    """The ``competition.yaml`` mapping (Codabench YAML version 2); phase dates by :func:`phase_dates`."""
    cols = leaderboard_columns(track)
    ph = []
    for i, (name, (begin, last)) in enumerate(zip(phases, phase_dates(len(phases), start, end))):
        ph.append({"index": i, "name": name, "description": f"{name} phase: scores the hidden test split",
                   "start": begin.isoformat(), "end": last.isoformat(),
                   "execution_time_limit": 3600, "tasks": [0],
                   **PHASE_LIMITS.get(name, PHASE_LIMITS["dev"])})
    return {"version": 2, "title": title, "description": f"Text-driven 3D human-object interaction generation, "
                                                         f"scored by hoibench {__version__} ({track} track)",
            "image": "logo.png", "docker_image": docker_image, "enable_detailed_results": True,
            "terms": "terms.md",
            "pages": [{"title": "Overview", "file": "overview.md"}, {"title": "Evaluation", "file": "evaluation.md"},
                      {"title": "Data", "file": "data.md"}],
            "tasks": [{"index": 0, "name": f"{track} generation", "description": "hidden test split",
                       "scoring_program": "scoring_program.zip", "reference_data": "reference_data.zip"}],
            "phases": ph,
            "leaderboards": [{"title": "Results", "key": "main", "columns": cols}]}


DOCKERFILE = """\
# The scoring image of a hoibench challenge (CPU only). Build it from a hoibench checkout:
#   docker build -f docker/Dockerfile -t {image} /path/to/hoibench
FROM python:3.11-slim
RUN apt-get update && apt-get install -y --no-install-recommends libusb-1.0-0 libgomp1 libgl1 \\
    && rm -rf /var/lib/apt/lists/*
RUN pip install --no-cache-dir torch --index-url https://download.pytorch.org/whl/cpu
COPY . /opt/hoibench
RUN pip install --no-cache-dir /opt/hoibench && python -c "import hoibench; print(hoibench.__version__)"
ENV HOIBENCH_PROGRESS=0 OMP_NUM_THREADS=1
"""

SCORE_PY = """\
# hoibench challenge scoring program: python3 score.py INPUT OUTPUT (Codabench: /app/input /app/output)
import sys
from hoibench.challenge.scoring import main
sys.exit(main(sys.argv[1:]))
"""


def _pages(title: str, track: str, protocol, evaluator_id: str, columns: list[dict]) -> dict[str, str]:
    metrics = ", ".join(c["title"] for c in columns if not c.get("hidden"))
    return {
        "overview.md": f"# {title}\n\nGenerate 3D human-object interaction motion from text. Submissions are "
                       f"scored on a hidden test split by hoibench {__version__} ({track} track).\n",
        "evaluation.md": f"# Evaluation\n\nProtocol `{protocol.ref}` (sha256 `{protocol.sha256[:12]}`), evaluator "
                         f"`{evaluator_id[:12]}`. Leaderboard columns: {metrics}. Every score is what "
                         f"`hoibench evaluate SUB --data DATA --evaluator EV --protocol {protocol.id}` gives; the "
                         f"detailed result page shows the full result with its 95% CIs.\n",
        "data.md": "# Data\n\nDownload the public data (train split with motions; test prompts: captions, lengths, "
                   "fps, object meshes). Write one `samples/<id>.npz` per prompt (docs/leaderboards.md), add "
                   "`submission.json`, check it with `hoibench validate`, zip the folder's contents and upload.\n",
        "terms.md": "# Terms\n\nSubmissions are scored automatically; scores and method names are public. The "
                    "test motions stay hidden. Use the data under the licence of the dataset it comes from.\n"}


def _logo_png() -> bytes:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig = plt.figure(figsize=(2, 2), dpi=64)
    fig.text(0.5, 0.5, "hoibench", ha="center", va="center", fontsize=18)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def _zip_folder(folder: Path) -> bytes:
    """A deterministic zip of ``folder``'s files (sorted, fixed timestamps)."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for p in sorted(q for q in folder.rglob("*") if q.is_file()):
            info = zipfile.ZipInfo(p.relative_to(folder).as_posix(), (1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            z.writestr(info, p.read_bytes())  # read-ok: files this function's caller just wrote
    return buf.getvalue()


def build_bundle(data: str | Path, evaluator: str | Path, out: str | Path, protocol: str | None = None,
                 title: str | None = None, phases: tuple[str, ...] = ("dev", "test"),
                 docker_image: str | None = None, start: date | None = None, end: date | None = None) -> Path:
    """Write the Codabench bundle ``out`` (a .zip); return its path. The phases run from
    ``start`` (default: today) to ``end`` (default: ``PHASE_DAYS`` days each), :func:`phase_dates`."""
    from ..core.io import atomic_write_bytes
    from ..datasets.store import Store
    from ..evaluator.backends import load_evaluator
    from ..tracks.protocol import default_protocol_id, get_protocol
    from ..tracks.registry import track_for_store
    from .reference import write_reference
    out = Path(out)
    if out.suffix != ".zip":
        raise ValueError(f"--out {out}: the bundle is a .zip file")
    if out.exists():
        raise ValueError(f"--out {out}: exists; choose a new file")
    if not phases or len(set(phases)) != len(phases) or not all(p.isidentifier() for p in phases):
        raise ValueError(f"--phases: expected distinct names such as dev,test, got {','.join(phases)!r}")
    start = start or date.today()
    phase_dates(len(phases), start, end)              # bad dates refused before any work
    store = Store(Path(data))
    track = track_for_store(store)
    proto = get_protocol(protocol or default_protocol_id(store.manifest))
    if proto.kind != "hoi":
        raise ValueError(f"--protocol {proto.ref}: hosted challenges score single-body (hoi) tracks")
    ev = load_evaluator(evaluator, kind=track.evaluator_kind, allow_failed_gate=True)
    title = title or f"hoibench {track.name} challenge"
    image = docker_image or f"hoibench/scorer:{__version__}"
    cols = leaderboard_columns(track.name)
    info = {"title": title, "track": track.name, "protocol": proto.id, "protocol_version": proto.version,
            "protocol_sha256": proto.sha256, "evaluator_id": ev.id, "split": proto.split,
            "columns": [c["key"] for c in cols if not c.get("hidden")], "phases": {p: proto.split for p in phases},
            "dataset": store.manifest.get("dataset"), "hoibench_version": __version__}
    members: dict[str, bytes] = {}
    with tempfile.TemporaryDirectory() as tmp:
        ref = write_reference(Path(data), Path(evaluator), Path(tmp) / "ref", info, proto.split)
        members["reference_data.zip"] = _zip_folder(ref)
        prog = Path(tmp) / "prog"
        prog.mkdir()
        (prog / "metadata.yaml").write_text(f"command: {SCORING_COMMAND}\n")
        (prog / "score.py").write_text(SCORE_PY)
        members["scoring_program.zip"] = _zip_folder(prog)
    members["competition.yaml"] = _yaml(competition_yaml(title, track.name, list(phases), image, start,
                                                         end)).encode()
    members.update({k: v.encode() for k, v in _pages(title, track.name, proto, ev.id, cols).items()})
    members["logo.png"] = _logo_png()
    members["docker/Dockerfile"] = DOCKERFILE.format(image=image).encode()
    members["challenge.json"] = (json.dumps({k: v for k, v in info.items()}, indent=1, sort_keys=True) + "\n").encode()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name in sorted(members):
            zi = zipfile.ZipInfo(name, (1980, 1, 1, 0, 0, 0))
            zi.compress_type = zipfile.ZIP_DEFLATED
            zi.external_attr = 0o644 << 16
            z.writestr(zi, members[name])
    return atomic_write_bytes(out, buf.getvalue())


def check_bundle(path: str | Path) -> list[str]:
    """Problems of a bundle against Codabench's v2 unpacker: required files and keys, every
    file the YAML names present, tasks with a scoring program, phases naming known tasks
    with ISO dates, leaderboard columns with title/key/index/sorting within Codabench's
    limits, and a scoring program with a ``command``. Empty when it would unpack."""
    return inspect_bundle(path)[0]


def inspect_bundle(path: str | Path, today: date | None = None) -> tuple[list[str], list[str]]:
    """``(problems, warnings)`` of a bundle: the problems of :func:`check_bundle` and the
    :func:`phase_warnings` of its phases on ``today`` (default: the current date)."""
    import yaml
    probs: list[str] = []
    warns: list[str] = []
    from ..core.io import read_regular_file
    data = read_regular_file(path, MAX_BUNDLE_BYTES, "bundle")
    with zipfile.ZipFile(io.BytesIO(data)) as z:  # read-ok: bytes read through the guarded reader
        names = set(z.namelist())
        big = [i.filename for i in z.infolist() if i.filename.endswith((".yaml", ".md")) and i.file_size > 1 << 20]
        if big:
            return [f"{big[0]}: over 1 MiB"], warns
        for f in REQUIRED_FILES:
            if f not in names:
                probs.append(f"missing file {f}")
        if "competition.yaml" not in names:
            return probs, warns
        comp = yaml.safe_load(z.read("competition.yaml"))  # read-ok: size checked above; safe_load builds plain data
        for k in REQUIRED_KEYS:
            if k not in comp:
                probs.append(f"competition.yaml: missing key {k}")
        if str(comp.get("version")) != "2":
            probs.append("competition.yaml: version must be 2")
        for page in comp.get("pages", []):
            if page.get("file") not in names or not z.read(page["file"]).strip():
                probs.append(f"page {page.get('file')}: missing or empty")
        tasks = {}
        for t in comp.get("tasks", []):
            if "index" not in t or t["index"] in tasks:
                probs.append(f"task {t.get('name')}: missing or duplicate index")
            tasks[t.get("index")] = t
            for kind in ("scoring_program", "reference_data", "input_data", "ingestion_program"):
                if kind in t and t[kind] not in names:
                    probs.append(f"task {t.get('index')}: {kind} {t[kind]} not in the bundle")
            if "scoring_program" not in t:
                probs.append(f"task {t.get('index')}: no scoring program")
            elif t["scoring_program"] in names:
                with zipfile.ZipFile(io.BytesIO(z.read(t["scoring_program"]))) as sp:
                    meta = (yaml.safe_load(sp.read("metadata.yaml"))  # read-ok: plain data from the bundle's own member
                            if "metadata.yaml" in sp.namelist() and sp.getinfo("metadata.yaml").file_size < 1 << 16
                            else None)
                    if not isinstance(meta, dict) or not meta.get("command"):
                        probs.append(f"task {t.get('index')}: scoring program without metadata.yaml command")
        for p in comp.get("phases", []):
            if not p.get("tasks") or any(i not in tasks for i in p["tasks"]):
                probs.append(f"phase {p.get('name')}: tasks {p.get('tasks')} unknown")
            for k in ("start", "end"):
                try:
                    if k in p:
                        date.fromisoformat(str(p[k]))
                except ValueError:
                    probs.append(f"phase {p.get('name')}: {k} {p[k]!r} is not an ISO date (YYYY-MM-DD)")
        warns += phase_warnings(comp.get("phases", []), today or date.today())
        for lb in comp.get("leaderboards", []):
            keys = set()
            for c in lb.get("columns", []):
                for k in ("title", "key", "index", "sorting"):
                    if k not in c:
                        probs.append(f"leaderboard {lb.get('key')}: column {c.get('key')} without {k}")
                if c.get("sorting") not in ("asc", "desc"):
                    probs.append(f"column {c.get('key')}: sorting must be asc or desc")
                if len(str(c.get("title", ""))) > MAX_KEY or len(str(c.get("key", ""))) > MAX_KEY:
                    probs.append(f"column {c.get('key')}: title or key longer than {MAX_KEY}")
                if c.get("key") in keys:
                    probs.append(f"column {c.get('key')}: duplicate key")
                keys.add(c.get("key"))
    return probs, warns


__all__ = ["REQUIRED_FILES", "REQUIRED_KEYS", "PHASE_DAYS", "leaderboard_columns", "phase_dates", "phase_warnings",
           "competition_yaml", "build_bundle", "check_bundle", "inspect_bundle"]
