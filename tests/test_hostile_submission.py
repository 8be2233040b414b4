"""Hostile submissions: every crafted case is refused with its id and field, within a memory
budget, without hanging, and the CLI answers each with one line and no traceback.

Families (docs/security.md): memory budget (huge or negative header claims, repeated
members, K over the protocol's cap, a deflate bomb), special files (FIFO, socket, device),
plausibility (1e30, a joint frame kilometres away, z-up), validation gaps (NaN fps, half
and extended precision, one non-finite joint, degenerate poses), container faults (corrupt,
encrypted, unsupported compression, deeply nested JSON), traversal (ids and zip members).
"""
from __future__ import annotations

import io
import json
import os
import shutil
import socket
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from hoibench.scoring import submission as S

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def gt_sub(synthetic_store, tmp_path_factory):
    """(store folder, ground-truth submission folder, test ids)."""
    _, data, manifest = synthetic_store
    out = tmp_path_factory.mktemp("hostile") / "gt"
    S.from_store(data, out)
    ids = sorted(c["id"] for c in manifest["clips"] if c["split"] == "test")
    return data, out, ids


# ---------------------------------------------------------------- crafting helpers
def _npy(shape, descr="<f4", payload=b"") -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": tuple(shape)})
    return buf.getvalue() + payload


def _zip(members, method=zipfile.ZIP_DEFLATED) -> bytes:
    buf = io.BytesIO()
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")        # "Duplicate name": on purpose
        with zipfile.ZipFile(buf, "w", method) as zf:
            for name, data in members:
                zf.writestr(name, data)
    return buf.getvalue()


def _arrays(sub: Path, sid: str) -> dict:
    with np.load(sub / "samples" / f"{sid}.npz", allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _save(sub: Path, sid: str, arrays: dict) -> None:
    (sub / "samples" / f"{sid}.npz").unlink()
    np.savez(sub / "samples" / f"{sid}.npz", **arrays)


def _deflate_bomb(path: Path, claim_bytes: int, shape) -> None:
    """An .npz whose joints member really holds ``claim_bytes`` of zeros (a few MB deflated)."""
    header = _npy(shape)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as zf:
        with zf.open("joints.npy", "w", force_zip64=True) as f:
            f.write(header)
            chunk = bytes(1 << 24)
            left = claim_bytes
            while left > 0:
                f.write(chunk[:min(left, len(chunk))])
                left -= len(chunk)


# Each case: name -> (build(sub, ids, tmp) -> path to validate, expected (id or None, field, needle))
def _case_huge_header(sub, ids, tmp):
    (sub / "samples" / f"{ids[0]}.npz").write_bytes(_zip([("joints.npy", _npy((40, 1_000_000, 22, 3)))]))
    return sub, (ids[0], "file", "limit")


def _case_negative_dim(sub, ids, tmp):
    (sub / "samples" / f"{ids[0]}.npz").write_bytes(_zip([("joints.npy", _npy((-1000, 100, 22, 3))),
                                                          ("joints.npy", _npy((6_000_000, 100, 22, 3)))]))
    return sub, (ids[0], "file", "negative")


def _case_zero_dim(sub, ids, tmp):
    (sub / "samples" / f"{ids[0]}.npz").write_bytes(_zip([("joints.npy", _npy((0, 10, 22, 3)))]))
    return sub, (ids[0], "file", "empty dimension")


def _case_duplicate_array(sub, ids, tmp):
    a = _arrays(sub, ids[0])
    good = io.BytesIO()
    np.save(good, a["joints"])
    members = [(f"{k}.npy", _npy_bytes(v)) for k, v in a.items()] + [("joints.npy", good.getvalue())]
    (sub / "samples" / f"{ids[0]}.npz").write_bytes(_zip(members))
    return sub, (ids[0], "file", "appears twice")


def _npy_bytes(a) -> bytes:
    b = io.BytesIO()
    np.save(b, a, allow_pickle=False)
    return b.getvalue()


def _case_k_over_cap(sub, ids, tmp):
    a = _arrays(sub, ids[0])
    _save(sub, ids[0], {k: np.repeat(v, 31, axis=0) for k, v in a.items()})
    return sub, (ids[0], "joints", "cap")


def _case_deflate_bomb(sub, ids, tmp):
    _deflate_bomb(sub / "samples" / f"{ids[0]}.npz", 256 * 1024 ** 2, (1, 256 * 1024 ** 2 // 264, 22, 3))
    return sub, (ids[0], "file", "budget")


def _case_duplicate_zip_member(sub, ids, tmp):
    z = tmp / "dup.zip"
    members = [(p.relative_to(sub).as_posix(), p.read_bytes()) for p in sorted(sub.rglob("*")) if p.is_file()]
    members.append((f"samples/{ids[0]}.npz", (sub / "samples" / f"{ids[1]}.npz").read_bytes()))
    z.write_bytes(_zip(members, zipfile.ZIP_STORED))
    return z, (ids[0], "file", "appears 2 times")


def _case_fifo_json(sub, ids, tmp):
    (sub / "submission.json").unlink()
    os.mkfifo(sub / "submission.json")
    return sub, ("*", "submission.json", "FIFO")


def _case_fifo_sample(sub, ids, tmp):
    (sub / "samples" / f"{ids[0]}.npz").unlink()
    os.mkfifo(sub / "samples" / f"{ids[0]}.npz")
    return sub, (ids[0], "file", "not a regular file")


def _case_fifo_submission(sub, ids, tmp):
    p = tmp / "fifo.zip"
    os.mkfifo(p)
    return p, ("*", "path", "neither a folder nor a regular file")


def _case_socket_sample(sub, ids, tmp):
    (sub / "samples" / f"{ids[0]}.npz").unlink()
    s = socket.socket(socket.AF_UNIX)
    short = Path("/tmp") / f"hb-{os.getpid()}-{abs(hash(str(tmp))) % 10 ** 8}.npz"
    s.bind(str(short))
    (sub / "samples" / f"{ids[0]}.npz").symlink_to(short)        # a socket, behind a link inside /tmp
    return sub, (ids[0], "file", "")


def _case_device_link(sub, ids, tmp):
    (sub / "samples" / f"{ids[0]}.npz").unlink()
    (sub / "samples" / f"{ids[0]}.npz").symlink_to("/dev/zero")
    return sub, (ids[0], "file", "link leaving")


def _case_inf_trans(sub, ids, tmp):
    a = _arrays(sub, ids[0])
    a["obj_trans"] = a["obj_trans"].copy()
    a["obj_trans"][0, 3] = 1e30
    _save(sub, ids[0], a)
    return sub, (ids[0], "obj_trans", "implausible")


def _case_far_joint_frame(sub, ids, tmp):
    a = _arrays(sub, ids[0])
    a["joints"] = a["joints"].copy()
    a["joints"][0, 5, :, 0] += 900.0                   # one frame 900 m away: within 1 km, not a human
    _save(sub, ids[0], a)
    return sub, (ids[0], "joints", "m/s")


def _case_one_nonfinite_joint(sub, ids, tmp):
    a = _arrays(sub, ids[1])
    a["joints"] = a["joints"].copy()
    a["joints"][0, 2, 7, 1] = np.inf
    _save(sub, ids[1], a)
    return sub, (ids[1], "joints", "non-finite")


def _dtype_case(field, dtype, needle):
    def build(sub, ids, tmp):
        a = _arrays(sub, ids[0])
        a[field] = a[field].astype(dtype)
        _save(sub, ids[0], a)
        return sub, (ids[0], field, needle)
    return build


_case_float16 = _dtype_case("obj_trans", np.float16, "float32 or float64")
_case_longdouble = _dtype_case("obj_rot", np.longdouble, "float32 or float64")
_case_complex = _dtype_case("obj_trans", np.complex64, "complex")


def _case_degenerate_pose(sub, ids, tmp):
    a = _arrays(sub, ids[0])
    j = a["joints"].copy()
    j[0, 4] = j[0, 4, :1]                               # every joint of frame 4 at the pelvis
    a["joints"] = j
    _save(sub, ids[0], a)
    return sub, (ids[0], "joints", "frame")


def _case_nan_fps(sub, ids, tmp):
    meta = json.loads((sub / "submission.json").read_text())
    (sub / "submission.json").write_text(json.dumps(meta).replace(f'"fps": {meta["fps"]}', '"fps": NaN'))
    return sub, ("*", "submission.json", "NaN")


def _case_nested_json(sub, ids, tmp):
    (sub / "submission.json").write_text("[" * 100_000 + "]" * 100_000)
    return sub, ("*", "submission.json", "nested too deeply")


def _case_z_up(sub, ids, tmp):
    swap = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], np.float32)      # y-up -> z-up
    for sid in ids:
        a = _arrays(sub, sid)
        a["joints"] = (a["joints"] @ swap.T).astype(np.float32)
        a["obj_trans"] = (a["obj_trans"] @ swap.T).astype(np.float32)
        a["obj_rot"] = (swap @ a["obj_rot"]).astype(np.float32)
        a.pop("hml263", None)
        _save(sub, sid, a)
    return sub, ("*", "joints", "z-up")


def _case_corrupt_member(sub, ids, tmp):
    raw = bytearray((sub / "samples" / f"{ids[0]}.npz").read_bytes())
    mid = len(raw) // 2
    raw[mid:mid + 64] = bytes(64)                       # corrupt deflate stream / CRC
    (sub / "samples" / f"{ids[0]}.npz").write_bytes(bytes(raw))
    return sub, (ids[0], "file", "")


def _patched_member(sub, sid, local_off: int, central_off: int, patch) -> None:
    """samples/<sid>.npz = a stored one-member .npz whose local and central headers get
    ``patch(bytearray, offset)`` at the given field offsets."""
    data = bytearray(_zip([("joints.npy", _npy((1, 10, 22, 3), payload=bytes(10 * 66 * 4)))], zipfile.ZIP_STORED))
    for sig, off in ((b"PK\x03\x04", local_off), (b"PK\x01\x02", central_off)):
        patch(data, data.find(sig) + off)
    (sub / "samples" / f"{sid}.npz").write_bytes(bytes(data))


def _case_encrypted_member(sub, ids, tmp):
    def encrypted(data, at):                                 # general-purpose flag bit 0
        data[at] |= 0x1
    _patched_member(sub, ids[0], 6, 8, encrypted)
    return sub, (ids[0], "file", "encrypted")


def _case_unsupported_compression(sub, ids, tmp):
    def method_99(data, at):                                 # method 99 (AES): not supported
        data[at:at + 2] = (99).to_bytes(2, "little")
    _patched_member(sub, ids[0], 8, 10, method_99)
    return sub, (ids[0], "file", "")


def _case_traversal_id(sub, ids, tmp):
    z = tmp / "trav.zip"
    members = [(p.relative_to(sub).as_posix(), p.read_bytes()) for p in sorted(sub.rglob("*")) if p.is_file()]
    members.append(("samples/..hidden.npz", b"x"))
    members.append(("samples/a b.npz", b"x"))
    z.write_bytes(_zip(members, zipfile.ZIP_STORED))
    return z, ("a b", "samples", "not a valid id")


CASES = {name[len("_case_"):]: fn for name, fn in sorted(globals().items()) if name.startswith("_case_")}


def _build(case, gt_sub, tmp_path):
    data, src, ids = gt_sub
    sub = tmp_path / "sub"
    shutil.copytree(src, sub)
    path, expect = CASES[case](sub, ids, tmp_path)
    return data, path, expect


@pytest.mark.parametrize("case", sorted(CASES))
def test_each_hostile_case_is_refused_naming_id_and_field(case, gt_sub, tmp_path):
    data, path, (sid, field, needle) = _build(case, gt_sub, tmp_path)
    rep = S.validation_report(path, data)
    errors = [p for p in rep.errors if p.id == sid and p.field == field]
    assert errors, [str(p) for p in rep.problems]
    assert any(needle.lower() in p.message.lower() for p in errors), [str(p) for p in errors]
    assert not rep.complete
    if sid not in ("*", None) and sid in rep.test_ids:
        assert sid not in rep.valid_ids
    # one bad id never spoils the others
    if sid not in ("*",) and case not in ("z_up",):
        others = [i for i in rep.test_ids if i != sid]
        assert set(others) <= set(rep.valid_ids), [str(p) for p in rep.errors]


def _built_cases(cases, gt_sub, tmp_path) -> list[str]:
    """Each case built in its own folder from a copy of the GT submission; their paths."""
    data, src, ids = gt_sub
    paths = []
    for case in cases:
        base = tmp_path / case
        base.mkdir()
        shutil.copytree(src, base / "sub")
        path, _ = CASES[case](base / "sub", ids, base)
        paths.append(str(path))
    return paths


def _child(script: str, data, paths) -> subprocess.CompletedProcess:
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-c", script, str(data), *paths], capture_output=True, text=True,
                          timeout=300, env=env)


def test_cli_answers_every_case_with_one_line_and_no_traceback(gt_sub, tmp_path):
    """Runs ``hoibench validate`` in a child process over every case (a FIFO must not hang it:
    the child has a time limit) and measures its peak RSS (``VmHWM`` of the child's own
    memory map: ``ru_maxrss`` would include the parent's high-water mark, which Linux carries
    across ``exec``)."""
    data = gt_sub[0]
    paths = _built_cases(sorted(CASES), gt_sub, tmp_path)
    script = (
        "import resource, sys, io, contextlib\n"
        "from hoibench.cli import main\n"
        "codes = []\n"
        "for p in sys.argv[2:]:\n"
        "    codes.append(main(['validate', p, '--data', sys.argv[1]]))\n"
        "print('CODES', codes)\n"
        "hwm = [ln for ln in open('/proc/self/status') if ln.startswith('VmHWM:')]\n"
        "print('MAXRSS_KB', hwm[0].split()[1] if hwm else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n")
    res = _child(script, data, paths)
    assert "Traceback" not in res.stderr and "Traceback" not in res.stdout, res.stderr[-3000:]
    codes = eval(res.stdout.split("CODES", 1)[1].splitlines()[0])
    want = [2 if case == "fifo_submission" else 1 for case in sorted(CASES)]   # no submission at all: 2
    assert codes == want, list(zip(sorted(CASES), codes))
    rss_mib = int(res.stdout.split("MAXRSS_KB", 1)[1].split()[0]) / 1024
    assert rss_mib < 1024, f"validate peaked at {rss_mib:.0f} MiB"


def test_memory_cases_are_refused_under_an_address_space_limit(gt_sub, tmp_path):
    """The budget cases under RLIMIT_AS = 1.5 GiB: refused with a message, not a crash."""
    data = gt_sub[0]
    paths = _built_cases(("huge_header", "negative_dim", "deflate_bomb", "k_over_cap", "duplicate_array"),
                         gt_sub, tmp_path)
    script = (
        "import resource, sys\n"
        "resource.setrlimit(resource.RLIMIT_AS, (1536 * 1024 ** 2, resource.RLIM_INFINITY))\n"
        "from hoibench.scoring.submission import validation_report\n"
        "for p in sys.argv[2:]:\n"
        "    rep = validation_report(p, sys.argv[1])\n"
        "    print('REFUSED' if not rep.complete else 'ACCEPTED', [str(e) for e in rep.errors][:1])\n")
    res = _child(script, data, paths)
    assert res.returncode == 0, res.stderr[-3000:]
    lines = [ln for ln in res.stdout.splitlines() if ln.startswith(("REFUSED", "ACCEPTED"))]
    assert len(lines) == len(paths) and all(ln.startswith("REFUSED") for ln in lines), res.stdout


def test_budgets_follow_the_test_split_and_the_protocol(gt_sub):
    from hoibench.tracks.protocol import get_protocol
    from hoibench.datasets.store import Store
    data, _, ids = gt_sub
    st = Store(data)
    proto = get_protocol("synthetic-clean")
    rows, fps, cap, _ = S.submission_context(st, proto)
    assert cap == max(proto.replications, proto.mm_samples) == 30
    lim = S.limits_for(rows, fps, cap)
    for sid in ids:
        T = int(rows[sid]["frames"])
        want = cap * max(4 * T, T + 10 * fps) * S.VALUES_PER_FRAME * 8 + S.FILE_OVERHEAD_BYTES
        assert lim.for_id(sid) == want
    assert lim.total_bytes == sum(lim.per_id_bytes.values())
    assert lim.largest_file_bytes < 256 * 1024 ** 2          # what validate holds at once, at most


def test_write_submission_refuses_ids_outside_the_rule(tmp_path):
    with pytest.raises(ValueError, match="not a valid id"):
        S.write_submission(tmp_path / "s", {"method": "m"}, {"../evil": {"joints": np.zeros((1, 2, 22, 3))}})
    assert not (tmp_path / "evil.npz").exists() and not (tmp_path / "s").exists()


def test_batched_encoding_keeps_each_samples_features_and_its_own_message(gt_sub, tmp_path):
    """Validation encodes the samples in batches (EncodeBatcher): the features it keeps for
    scoring are bit-identical to encoding each sample alone, and a file whose second sample
    encodes to non-finite features is refused with the message the one-at-a-time check gives
    (naming sample 1 and the frame), while the other files stay valid."""
    import shutil
    from hoibench.scoring.read_cache import ReadCache
    from hoibench.scoring.validate import validation_report
    from hoibench.scoring.validate_arrays import ClipContext, _check_encodes, encode_sample
    data, sub, ids = gt_sub
    mine = tmp_path / "sub"
    shutil.copytree(sub, mine)
    bad = ids[0]
    a = _arrays(mine, bad)
    a = {k: np.concatenate([v, v], 0) for k, v in a.items()}         # K = 2 ...
    a["joints"][1, 4, 2] = a["joints"][1, 4, 1]                      # ... the second: coincident hips and
    a["joints"][1, 4, 17] = a["joints"][1, 4, 16]                    # shoulders at frame 4 (no facing)
    _save(mine, bad, a)
    for sid in ids[1:]:                                              # every other file: K = 2 as well
        b = _arrays(mine, sid)
        _save(mine, sid, {k: np.concatenate([v, v], 0) for k, v in b.items()})
    cache = ReadCache()
    report = validation_report(mine, data, keep=cache)
    (problem,) = [p for p in report.problems if p.id == bad and p.severity == "error"]
    fps = 20.0
    alone = _check_encodes(bad, _arrays(mine, bad), ClipContext(0, True, fps, False, 30, "clean"))
    assert problem.field == "joints" and problem.message == alone[0].message and "sample 1" in problem.message
    assert sorted(report.valid_ids) == sorted(ids[1:]) and cache.take_arrays(bad) is None
    for sid in ids[1:]:
        arrays = _arrays(mine, sid)
        for k in range(2):
            kept = cache.take_features(sid, k)
            assert kept is not None and np.array_equal(kept, encode_sample(arrays, k, "clean", fps))


def test_a_file_that_is_not_a_zip_is_one_error_and_a_misfit_protocol_is_noted(gt_sub, tmp_path, capsys):
    from hoibench.cli import main
    data, gt, ids = gt_sub
    bad = tmp_path / "notzip.zip"
    bad.write_text("not a zip")
    assert main(["validate", str(bad), "--data", str(data)]) == 1
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 2 and "neither a folder nor a valid .zip" in out[0] and f"0 of {len(ids)} test ids" in out[1]
    assert main(["validate", str(gt), "--data", str(data), "--protocol", "behave-clean"]) == 0
    out = capsys.readouterr().out
    assert "note: --protocol behave-clean does not fit the store" in out and "dataset 'behave'" in out


def test_a_truncated_zip_is_one_error_not_an_inner_npz_read_as_the_submission(gt_sub, tmp_path, capsys):
    """A submission zip stores its .npz members as they are, so a file cut at the end of one
    of them ends with that member's own zip directory; zipfile opens it as the submission."""
    import zipfile
    from hoibench.cli import main
    data, gt, ids = gt_sub
    whole = tmp_path / "whole.zip"
    with zipfile.ZipFile(whole, "w", compression=zipfile.ZIP_STORED) as zf:
        for f in sorted(p for p in gt.rglob("*") if p.is_file()):
            zf.write(f, f.relative_to(gt).as_posix())
    with zipfile.ZipFile(whole) as zf:
        cut = zf.infolist()[-1].header_offset                       # the end of the member before the last
    cut_file = tmp_path / "cut.zip"
    cut_file.write_bytes(whole.read_bytes()[:cut])
    with zipfile.ZipFile(cut_file) as zf:                            # what zipfile alone makes of it
        assert any(n.endswith(".npy") for n in zf.namelist())
    assert main(["validate", str(whole), "--data", str(data)]) == 0
    capsys.readouterr()
    assert main(["validate", str(cut_file), "--data", str(data)]) == 1
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 2 and "truncated" in out[0] and f"0 of {len(ids)} test ids" in out[1]
