"""Strict readers: JSON numbers must be finite; a corrupt clip file is named, never unpickled."""
from __future__ import annotations

import shutil

import pytest

from hoibench.core.io import load_json_bytes
from hoibench.datasets.store import Store


@pytest.mark.parametrize("raw", [b'{"guidance": 1e999}', b'[-1e400]', b'{"a": NaN}', b'{"a": Infinity}'])
def test_json_numbers_must_be_finite(raw):
    with pytest.raises(ValueError, match="card.json: not valid JSON: .*finite"):
        load_json_bytes(raw, "card.json")


def test_large_but_finite_numbers_still_load():
    assert load_json_bytes(b'{"a": 1e308, "b": -2.5e-300}', "x") == {"a": 1e308, "b": -2.5e-300}


def test_a_corrupt_clip_file_is_named_and_never_unpickled(template_store, tmp_path):
    copy = tmp_path / "data"
    shutil.copytree(template_store, copy)
    st = Store(copy)
    cid = st.clip_ids()[0]
    (copy / "clips" / f"{cid}.npz").write_bytes(b"garbage that is not a zip archive")
    with pytest.raises(ValueError) as err:
        st.load(cid)
    msg = str(err.value)
    assert str(copy / "clips" / f"{cid}.npz") in msg and "pickle" not in msg
    (copy / "clips" / f"{cid}.npz").unlink()
    with pytest.raises(FileNotFoundError, match="in the manifest but its file is not"):
        st.load(cid)
