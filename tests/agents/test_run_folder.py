"""The run folder's lock: one training process at a time; a lock left by a killed process never blocks."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from tsrl.agents.run_folder import LOCK, RunLock, RunLocked


def test_a_held_lock_refuses_a_second_holder_naming_the_pid(tmp_path):
    with RunLock(tmp_path):
        assert (tmp_path / LOCK).read_text().strip() == str(os.getpid())
        with pytest.raises(RunLocked, match=f"being trained by process {os.getpid()};"), RunLock(tmp_path):
            pass
    assert not (tmp_path / LOCK).exists()  # released and removed


def test_a_lock_file_left_by_a_killed_process_does_not_block(tmp_path):
    code = (
        "import os, sys; from pathlib import Path; from tsrl.agents.run_folder import RunLock; "
        "RunLock(Path(sys.argv[1])).__enter__(); os._exit(9)"  # killed while holding the lock
    )
    dead = subprocess.run([sys.executable, "-c", code, str(tmp_path)], check=False)
    assert dead.returncode == 9 and (tmp_path / LOCK).is_file()  # exited holding it: the file stays
    with RunLock(tmp_path):
        assert (tmp_path / LOCK).read_text().strip() == str(os.getpid())
