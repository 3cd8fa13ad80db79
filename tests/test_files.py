"""tsrl.files: atomic writes leave the old version or the new one, and no temporaries."""

import os

import numpy as np
import pytest

from tsrl.files import replacing, temporary_name, write_atomic


def test_write_atomic_writes_text_and_bytes_and_replaces_the_old_file(tmp_path):
    path = tmp_path / "a.json"
    assert write_atomic(path, "{}\n") == path
    assert path.read_text() == "{}\n"
    write_atomic(path, b"\x00\x01")
    assert path.read_bytes() == b"\x00\x01"
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]


def test_a_write_that_fails_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "progress.csv"
    path.write_text("old\n")
    with pytest.raises(RuntimeError, match="disk full"), replacing(path) as tmp:
        tmp.write_text("half a fi")
        raise RuntimeError("disk full")
    assert path.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["progress.csv"]


def test_the_temporary_is_hidden_beside_the_file_named_by_the_process_and_ends_in_the_suffix(tmp_path):
    tmp = temporary_name(tmp_path / "demos.npz", suffix=".npz")
    assert tmp.parent == tmp_path
    assert tmp.name == f".demos.npz.{os.getpid()}.tmp.npz"
    with replacing(tmp_path / "demos.npz", suffix=".npz") as tmp:
        np.savez_compressed(tmp, x=np.arange(3))  # numpy keeps a name ending in .npz as it is
    with np.load(tmp_path / "demos.npz") as f:
        np.testing.assert_array_equal(f["x"], np.arange(3))


def test_a_folder_replaces_a_folder_whole(tmp_path):
    final = tmp_path / "step_0000000200"
    final.mkdir()
    (final / "model.zip").write_text("damaged")
    with replacing(final) as tmp:
        tmp.mkdir()
        (tmp / "model.zip").write_text("new")
        (tmp / "state.json").write_text("{}")
    assert sorted(p.name for p in final.iterdir()) == ["model.zip", "state.json"]
    assert (final / "model.zip").read_text() == "new"
    assert [p.name for p in tmp_path.iterdir()] == ["step_0000000200"]


def test_a_leftover_temporary_of_a_killed_process_with_the_same_pid_is_cleared(tmp_path):
    path = tmp_path / "config.json"
    stale = temporary_name(path)
    stale.mkdir()  # a checkpoint-style folder left half written
    (stale / "junk").write_text("x")
    write_atomic(path, "{}")
    assert path.read_text() == "{}"
    assert not stale.exists()
