"""Checks that Blender can read and mesh a grid, in a separate background Blender.

Blender 3.4 reads voxel data lazily and aborts the whole program when OpenVDB throws while it
does (``terminate called after throwing an instance of 'openvdb::RuntimeError'``), e.g. on a
``.vdb`` whose voxel data is damaged although its structure is intact. Loading and meshing the
grid once in a child Blender (``vdb_probe_child.py``) turns such a crash into an error message
for the user, and this session never touches the bad data.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import tempfile

import bpy

from .vdb_header import VdbFileError

_CHILD_SCRIPT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "vdb_probe_child.py")
# The child meshes the 8 MB surface of the bundled street in under 2 s; one still busy after this
# long is stuck (a safety net: with one thread, damaged data has made it abort, not hang).
_TIMEOUT_BASE_S = 60.0
_TIMEOUT_S_PER_MB = 1.0


def verify_grid_in_subprocess(path: str, grid_name: str) -> None:
    """Loads grid ``grid_name`` of ``path`` and meshes it at iso 0 in a child Blender.

    Raises:
        VdbFileError: the child reported an error, crashed or timed out; the message names the
            file, the grid and the reason (OpenVDB's own message when it aborted).
    """
    timeout_s = _TIMEOUT_BASE_S + _TIMEOUT_S_PER_MB * os.path.getsize(path) / 1e6
    with tempfile.TemporaryDirectory(prefix="shinevdb_probe_") as tmp_dir:
        result_path = os.path.join(tmp_dir, "result.json")
        command = [
            bpy.app.binary_path, "--background", "--factory-startup",
            # With several threads, OpenVDB's lazy loading of damaged voxel data sometimes hangs
            # (a worker spins on a leaf's lock after another threw); with one thread it aborted
            # or crashed in every trial here.
            "--threads", "1",
            "--python-exit-code", "1", "--python", _CHILD_SCRIPT,
            "--", path, grid_name, result_path,
        ]  # fmt: skip
        try:
            child = subprocess.run(command, capture_output=True, text=True, timeout=timeout_s)
        except subprocess.TimeoutExpired:
            raise VdbFileError(
                f"'{path}' may be corrupt: checking grid '{grid_name}' in a separate Blender "
                f"took more than {timeout_s:.0f} s (disable 'Check in a Separate Blender' to "
                "import it anyway)"
            ) from None
        result = {}
        if os.path.isfile(result_path):
            with open(result_path, encoding="utf-8") as result_file:
                result = json.load(result_file)
    if child.returncode == 0 and result.get("ok"):
        return
    reason = result.get("error") or _crash_reason(child)
    raise VdbFileError(f"'{path}' is corrupt or unreadable: grid '{grid_name}': {reason}")


def _crash_reason(child: subprocess.CompletedProcess) -> str:
    """Explains why the child Blender stopped without a result, from its exit status and stderr."""
    for line in reversed(child.stderr.splitlines()):
        # The C++ runtime's last words when an exception escapes: "  what():  <message>".
        if "what():" in line:
            return "OpenVDB: " + line.split("what():", 1)[1].strip()
    if child.returncode < 0:
        return f"Blender crashed reading it (signal {signal.Signals(-child.returncode).name})"
    last_lines = [line for line in child.stderr.splitlines() if line.strip()][-3:]
    detail = f": {' / '.join(last_lines)}" if last_lines else ""
    return f"Blender exited with code {child.returncode} reading it{detail}"
