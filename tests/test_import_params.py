"""``hoibench import params``: per-frame body parameters posed with the user's body model
(the proxy here) give the joints that hoibench's independent numpy skinning of the same
parameters gives; z-up sources and object poses turn y-up together; bad files are one line
naming the file and field."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from hoibench.bodies import write_proxy_model
from hoibench.bodies.proxy import ProxyBody
from hoibench.core.geometry import axis_angle_to_matrix
from hoibench.scoring.importers import ImportProblem, import_results
from hoibench.scoring.import_params import Z_TO_Y

pytest.importorskip("smplx")


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    root = tmp_path_factory.mktemp("models")
    write_proxy_model(root, "smplh")
    return root


def _params(T: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    return {"poses": rng.normal(scale=0.3, size=(T, 156)), "betas": rng.normal(size=10),
            "trans": np.cumsum(rng.normal(scale=0.01, size=(T, 3)), 0) + [0.0, 0.9, 0.0]}


def test_params_files_pose_to_the_independent_skinning_of_the_same_parameters(template_store, models, tmp_path):
    from hoibench.datasets.store import Store
    st = Store(template_store)
    ids = st.clip_ids("test")[:3]
    folder = tmp_path / "params"
    folder.mkdir()
    want = {}
    proxy = ProxyBody("smplh")
    for i, cid in enumerate(ids):
        clip = st.load(cid)
        T = len(clip["joints"])
        for r in range(2):
            p = _params(T, 10 * i + r)
            np.savez(folder / f"{cid}_{r}.npz", **p, obj_rot=clip["obj_rot"], obj_trans=clip["obj_trans"])
            want.setdefault(cid, []).append(proxy.forward(p["poses"], p["trans"], p["betas"])[1])
    sub, rep = import_results("params", folder, template_store, tmp_path / "sub", body_models=models, fps=20.0)
    assert rep["matched"] == 3 and rep["samples_per_prompt"] == [2] and not rep["human_only"]
    for cid in ids:
        with np.load(sub / "samples" / f"{cid}.npz") as z:
            np.testing.assert_allclose(z["joints"], np.stack(want[cid]), atol=2e-5)
            np.testing.assert_allclose(axis_angle_to_matrix(z["obj_rotvec"][0].astype(np.float64)),
                                       st.load(cid)["obj_rot"], atol=1e-5)
    meta = json.loads((sub / "submission.json").read_text())
    assert meta["source"]["import"]["body_model"] == "smplh"


def test_z_up_params_turn_y_up_with_their_object_and_human_only_is_flagged(template_store, models, tmp_path):
    from hoibench.datasets.store import Store
    st = Store(template_store)
    cid = st.clip_ids("test")[0]
    T = len(st.load(cid)["joints"])
    p = _params(T, 3)
    R = axis_angle_to_matrix(np.tile([0.0, 0.0, 0.7], (T, 1)))
    t = np.tile([0.5, 0.2, 0.8], (T, 1))
    a, b = tmp_path / "y", tmp_path / "z"
    a.mkdir(), b.mkdir()
    np.savez(a / f"{cid}.npz", **p)
    np.savez(b / f"{cid}.npz", **p, obj_rot=R, obj_trans=t)
    suba, repa = import_results("params", a, template_store, tmp_path / "sa", body_models=models, fps=20.0)
    subb, _ = import_results("params", b, template_store, tmp_path / "sb", body_models=models, fps=20.0, up="z")
    assert repa["human_only"] and json.loads((suba / "submission.json").read_text())["flags"]["human_only"]
    with np.load(suba / "samples" / f"{cid}.npz") as ya, np.load(subb / "samples" / f"{cid}.npz") as zb:
        np.testing.assert_allclose(zb["joints"][0], ya["joints"][0] @ Z_TO_Y.T, atol=1e-5)
        np.testing.assert_allclose(zb["obj_trans"][0], t @ Z_TO_Y.T, atol=1e-5)
        np.testing.assert_allclose(axis_angle_to_matrix(zb["obj_rotvec"][0].astype(np.float64)),
                                   np.einsum("ij,tjk->tik", Z_TO_Y, R), atol=1e-5)


@pytest.mark.parametrize("change, field", [({"poses": np.zeros((30, 70))}, "poses"),
                                           ({"trans": np.zeros((29, 3))}, "trans"),
                                           ({"betas": np.full(10, np.nan)}, "betas"),
                                           ({"obj_rot": np.tile(np.eye(3), (30, 1, 1))}, "obj_trans")])
def test_bad_params_files_are_one_line_naming_file_and_field(template_store, models, tmp_path, change, field):
    from hoibench.datasets.store import Store
    cid = Store(template_store).clip_ids("test")[0]
    folder = tmp_path / "bad"
    folder.mkdir()
    np.savez(folder / f"{cid}.npz", **{**_params(30, 0), **change})
    with pytest.raises(ImportProblem, match=rf"{cid}\.npz: field {field}"):
        import_results("params", folder, template_store, tmp_path / "s", body_models=models)
    if field != "poses":
        return                                   # the command line once is enough
    r = subprocess.run([sys.executable, "-m", "hoibench.cli", "import", "params", str(folder), "--data",
                        str(template_store), "--out", str(tmp_path / "cli"), "--body-models", str(models)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and f"field {field}" in r.stderr
