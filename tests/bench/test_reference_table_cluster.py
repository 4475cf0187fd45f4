"""The Ray cluster of the reference table's cluster bench (``bench/reference_table_cluster.py``)
leaves nothing behind: its nodes keep Ray's address file in a folder of their own, removed
with them, never in the shared ``/tmp/ray`` where a later ``ray.init()`` would read it."""

import os
import socket
import time
from pathlib import Path

import pytest

from bench.reference_table_cluster import _start, _stop, _temp_dir


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.slow
def test_a_head_node_writes_its_address_in_its_own_folder_and_leaves_nothing(tmp_path):
    port = _free_port()
    temp = _temp_dir()
    head = _start(["--head", "--port", str(port), "--num-cpus", "1", "--include-dashboard",
                   "false"], tmp_path / "head.log", temp)
    address_file = temp / "ray_current_cluster"
    try:
        for _ in range(600):                     # waits for the node, at most 2 min
            if address_file.exists() or head.poll() is not None:
                break
            time.sleep(0.2)
        assert address_file.exists(), (tmp_path / "head.log").read_text()[-2000:]
        ours = address_file.read_text().strip()
        assert ours.endswith(f":{port}")
    finally:
        _stop([head], temp)
    assert not temp.exists()
    shared = Path("/tmp/ray/ray_current_cluster")
    assert not (shared.exists() and shared.read_text().strip() == ours)
    with pytest.raises(ProcessLookupError):      # the node's whole process group is gone
        os.killpg(head.pid, 0)
