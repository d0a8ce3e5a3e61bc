"""The sidebar's Map Scans operator: shine found on PATH, a run with progress and import, CLI
errors shown, cancellation.

Args (after ``--``): --addon-zip ZIP --scans DIR (a tiny simulated sequence) --shine PATH (the
``shine`` on PATH, to compare with what the add-on finds) --work-dir DIR.

Background Blender fires no timers, so the test drives the run with ``map_run.step`` (the
function the operator registers as a timer) and ``map_run.wait_until_done`` (which calls it).
The add-on's modules are imported inside the checks: they exist only once it is installed.
"""

import json
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import shinevdb_test_support as support  # noqa: E402
from shinevdb_test_support import expect  # noqa: E402

LEAF_SIZE_M = 0.25  # not shine's default, to see that the setting reaches the CLI
ITERATIONS = 200
RUN_TIMEOUT_S = 240.0


def run_map_operator() -> None:
    """Starts a run through the operator, as the panel's button does."""
    expect(bpy.ops.shinevdb.run_map() == {"FINISHED"}, "Map Scans did not start")


def expect_operator_error(phrase: str) -> None:
    """Map Scans refuses to start, with an error report containing ``phrase``."""
    try:
        bpy.ops.shinevdb.run_map()
    except RuntimeError as error:
        print(f"refused as expected: {str(error).strip()}")
        expect(phrase in str(error), f"expected '{phrase}' in: {error}")
        return
    raise AssertionError(f"Map Scans started although it should fail with '{phrase}'")


def check_finding_shine(shine: str, preferences) -> None:
    """An empty preference finds shine on PATH; a wrong path is reported, not guessed around."""
    from shinevdb.preferences import resolve_shine_executable

    expect(preferences.shine_path == "", "the default preference should be empty (use PATH)")
    found = resolve_shine_executable(preferences.shine_path)
    expect(os.path.samefile(found, shine), f"found {found} on PATH instead of {shine}")
    preferences.shine_path = "/nonexistent/shine"
    expect_operator_error("/nonexistent/shine")
    preferences.shine_path = ""


def check_successful_run(settings, output_dir: str) -> None:
    """A short mapping run: returns at once, reports progress, imports a surface that matches
    the run's mesh.ply."""
    from shinevdb import map_run

    settings.output_dir = output_dir
    settings.leaf_size_m = LEAF_SIZE_M
    settings.iterations = ITERATIONS
    settings.extra_args = "--no-eval --threads 2"
    started = time.monotonic()
    run_map_operator()
    expect(time.monotonic() - started < 1.0 and map_run.is_running(),
           "the operator should return while shine is still running")
    stages = {}
    deadline = started + RUN_TIMEOUT_S
    while map_run.is_running():  # what Blender's timer does, a few times a second
        expect(time.monotonic() < deadline, "shine map took too long")
        if map_run.step() is not None:
            progress = map_run.current().job.progress
            if progress is not None:
                stages[progress.stage] = progress
            time.sleep(map_run.POLL_INTERVAL_S)
    run = map_run.current()
    print(f"run ended '{run.state}' after {time.monotonic() - started:.1f} s; progress seen: "
          + ", ".join(f"{p.stage} {p.done}/{p.total}" for p in stages.values()))
    expect(run.state == "done", f"the run ended '{run.state}': {run.error}")
    expect("train" in stages and stages["train"].total == ITERATIONS,
           f"no train progress over {ITERATIONS} iterations was parsed: {stages}")
    expect(bpy.context.window_manager.shinevdb_progress == 100.0, "progress bar not at 100 %")
    print("\n".join(run.summary))

    with open(os.path.join(output_dir, "stats.json"), encoding="utf-8") as stats_file:
        stats = json.load(stats_file)
    expect(stats["leaf_size_m"] == LEAF_SIZE_M and stats["iterations"] == ITERATIONS,
           f"the panel's settings did not reach shine: {stats}")
    mesh_object = bpy.data.objects[run.imported_object]
    expect(bpy.context.view_layer.objects.active == mesh_object, "the import is not active")
    support.check_coincides(mesh_object, os.path.join(output_dir, "mesh.ply"),
                            stats["surface"]["voxel_size_m"], "imported after the run")


def check_cli_error_is_shown(settings, empty_dir: str) -> None:
    """shine's own error message (here: a folder without scans) ends up in the run's error."""
    from shinevdb import map_run

    objects_before = len(bpy.data.objects)
    settings.scan_dir = empty_dir
    run_map_operator()
    run = map_run.wait_until_done(RUN_TIMEOUT_S)
    print(f"CLI error shown to the user: {run.error}")
    expect(run.state == "failed", f"a run on an empty folder ended '{run.state}'")
    expect(empty_dir in run.error and not run.error.startswith("shine exited"),
           f"the error is not shine's message about {empty_dir}: {run.error}")
    expect(len(bpy.data.objects) == objects_before, "a failed run imported something")


def check_cancel(settings, output_dir: str) -> None:
    """Cancel stops shine; nothing is imported or left in the output folder."""
    from shinevdb import map_run

    objects_before = len(bpy.data.objects)
    settings.output_dir = output_dir
    settings.iterations = 1_000_000
    run_map_operator()
    deadline = time.monotonic() + RUN_TIMEOUT_S
    job = map_run.current().job
    # Cancel while training: the first map of the pose refinement ("refine") or the map itself.
    while job.progress is None or job.progress.stage not in ("refine", "train"):
        expect(time.monotonic() < deadline, "shine map did not start training")
        still_running = map_run.step() is not None
        expect(still_running, f"shine ended before training: {map_run.current().error}")
        time.sleep(map_run.POLL_INTERVAL_S)
    expect(bpy.ops.shinevdb.cancel_map() == {"FINISHED"}, "Cancel failed")
    run = map_run.wait_until_done(RUN_TIMEOUT_S)
    expect(run.state == "cancelled", f"a cancelled run ended '{run.state}'")
    expect(len(bpy.data.objects) == objects_before, "a cancelled run imported something")
    expect(not os.path.exists(os.path.join(output_dir, "surface.vdb")),
           "a cancelled run left a surface.vdb")


def main() -> None:
    args = support.parse_args("addon-zip", "scans", "shine", "work-dir")
    work_dir = support.fresh_dir(args.work_dir)
    support.install_addon(args.addon_zip, args.work_dir)
    support.clear_scene()
    preferences = bpy.context.preferences.addons[support.ADDON_MODULE].preferences
    settings = bpy.context.scene.shinevdb_map

    check_finding_shine(args.shine, preferences)
    settings.scan_dir = os.path.join(work_dir, "no_such_folder")
    expect_operator_error("does not exist")
    settings.scan_dir = args.scans
    check_successful_run(settings, os.path.join(work_dir, "out"))
    empty_dir = os.path.join(work_dir, "empty_scans")
    os.makedirs(empty_dir)
    check_cli_error_is_shown(settings, empty_dir)
    settings.scan_dir = args.scans
    check_cancel(settings, os.path.join(work_dir, "cancelled"))
    print("test_map_operator: all checks passed")


main()
