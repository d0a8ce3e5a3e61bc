"""A corrupt or unsuitable .vdb gives a clear error naming the file and the problem, and no objects.

Args (after ``--``): --addon-zip ZIP --fixture DIR (``surface.vdb``, ``map.vdb`` made by
``shine``) --work-dir DIR.
"""

import os
import shutil
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import shinevdb_test_support as support  # noqa: E402
from shinevdb_test_support import expect  # noqa: E402

DAMAGED_BYTES = 256 * 1024  # overwritten in the middle of the voxel data


def make_bad_files(fixture: str, work_dir: str) -> dict:
    """Writes the bad inputs; returns {path: phrase its error message must contain}."""
    rng = np.random.default_rng(7)
    surface = os.path.join(fixture, "surface.vdb")
    with open(surface, "rb") as surface_file:
        good = surface_file.read()
    contents = {
        "garbage.vdb": rng.integers(0, 256, 4096, dtype=np.uint8).tobytes(),
        "empty.vdb": b"",
        "truncated.vdb": good[: len(good) // 2],
    }
    middle = len(good) // 2
    damaged = bytearray(good)
    noise = rng.integers(0, 256, DAMAGED_BYTES, dtype=np.uint8).tobytes()
    damaged[middle : middle + DAMAGED_BYTES] = noise
    contents["damaged.vdb"] = bytes(damaged)
    for name, data in contents.items():
        with open(os.path.join(work_dir, name), "wb") as bad_file:
            bad_file.write(data)
    map_copy = os.path.join(work_dir, "map.vdb")  # a valid .vdb without a level-set grid
    shutil.copyfile(os.path.join(fixture, "map.vdb"), map_copy)
    return {
        os.path.join(work_dir, "garbage.vdb"): "does not start with the OpenVDB magic number",
        os.path.join(work_dir, "empty.vdb"): "does not start with the OpenVDB magic number",
        os.path.join(work_dir, "truncated.vdb"): "the file is truncated",
        os.path.join(work_dir, "damaged.vdb"): "is corrupt or unreadable",
        map_copy: "has no grid named 'surface'",
        os.path.join(work_dir, "missing.vdb"): "does not exist",
    }


def data_block_count() -> int:
    return len(bpy.data.objects) + len(bpy.data.meshes) + len(bpy.data.volumes)


def check_rejected(path: str, phrase: str) -> None:
    """The import fails with an error naming ``path`` and containing ``phrase``; nothing is made."""
    before = data_block_count()
    try:
        result = bpy.ops.import_scene.shinevdb_level_set(filepath=path)
    except RuntimeError as error:  # how bpy.ops returns an operator's error report
        message = str(error)
    else:
        raise AssertionError(f"importing {path} did not fail (returned {result})")
    print(f"{os.path.basename(path)}: {message.strip()}")
    expect(path in message, f"the error for {path} does not name the file: {message}")
    expect(phrase in message, f"the error for {path} does not say '{phrase}': {message}")
    expect("Traceback" not in message, f"the error for {path} is a traceback: {message}")
    expect(data_block_count() == before, f"the failed import of {path} left data behind")


def main() -> None:
    args = support.parse_args("addon-zip", "fixture", "work-dir")
    work_dir = support.fresh_dir(args.work_dir)
    support.install_addon(args.addon_zip, args.work_dir)
    support.clear_scene()
    for path, phrase in make_bad_files(args.fixture, work_dir).items():
        check_rejected(path, phrase)
    # This Blender is unharmed: a good file still imports.
    result = bpy.ops.import_scene.shinevdb_level_set(
        filepath=os.path.join(args.fixture, "surface.vdb"))
    expect(result == {"FINISHED"} and len(bpy.data.objects) == 1,
           "a good file should import after the bad ones")
    print("test_corrupt_file: all checks passed")


main()
