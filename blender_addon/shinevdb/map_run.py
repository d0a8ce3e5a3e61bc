"""This Blender session's ``shine map`` run: start it, follow it from a timer, import the result.

Blender's interface stays responsive because nothing here waits for ``shine``: :func:`start`
launches a :class:`~.map_job.MapJob` and registers :func:`step` as a ``bpy.app.timers`` callback,
which takes in the job's output a few times a second and, once the job has ended, imports
``OUT/surface.vdb`` (with the colours and intensity of ``OUT/mesh.ply`` when the map has them,
as File › Import does) or records the error for the panel (and pops it up). Background scripts and
tests, where timers do not fire, call :func:`wait_until_done`, which runs the same :func:`step`.
"""

from __future__ import annotations

import os
import shlex
import sys
import textwrap
import time
from dataclasses import dataclass, field, replace
from typing import List, Optional

import bpy
from bpy.props import FloatProperty

from . import level_set_import
from .map_job import MapJob

POLL_INTERVAL_S = 0.25
SURFACE_FILE = "surface.vdb"  # what `shine map` writes next to map.vdb and mesh.ply


class MapRunError(Exception):
    """A run cannot start; the message says why."""


@dataclass
class MapRequest:
    """What to map and how; mirrors the panel's settings."""

    scan_dir: str
    output_dir: str  # empty: "<scan_dir>_shine" next to the scan folder
    leaf_size_m: float
    mode: str
    iterations: int  # 0: shine's default
    extra_args: str  # more `shine map` options, shell-quoted


@dataclass
class MapRun:
    """A started run and, once it has ended, its outcome."""

    job: MapJob
    output_dir: str
    scene_name: str
    view_layer_name: str
    state: str = "running"  # then "done", "failed" or "cancelled"
    error: str = ""
    summary: List[str] = field(default_factory=list)  # shine's stdout and the import, when done
    imported_object: str = ""


_run: Optional[MapRun] = None  # the running run, or the last one (its outcome stays on the panel)


def current() -> Optional[MapRun]:
    """The running run, or the last one of this session, or None."""
    return _run


def is_running() -> bool:
    """True while a run is going."""
    return _run is not None and _run.state == "running"


def _build_command(shine: str, request: MapRequest, output_dir: str) -> List[str]:
    """The ``shine map`` command line for ``request``.

    Raises:
        MapRunError: ``extra_args`` is not valid shell quoting.
    """
    command = [shine, "map", request.scan_dir, "--output", output_dir,
               # A Blender float is single precision: 0.2 reads back as 0.20000000298...
               "--leaf-size-m", f"{request.leaf_size_m:.6g}", "--mode", request.mode]
    if request.iterations > 0:
        command += ["--iterations", str(request.iterations)]
    try:
        return command + shlex.split(request.extra_args)
    except ValueError as error:
        raise MapRunError(f"extra arguments '{request.extra_args}': {error}") from None


def start(shine: str, request: MapRequest, scene: bpy.types.Scene,
          view_layer: bpy.types.ViewLayer) -> MapRun:
    """Starts ``shine map`` for ``request``; its result is imported into ``view_layer``'s active
    collection when it finishes.

    Raises:
        MapRunError: a run is already going, the scan folder is not set or does not exist, the
            extra arguments are not valid shell quoting, or ``shine`` cannot be started.
    """
    global _run
    if is_running():
        raise MapRunError("a mapping run is already going; wait for it or cancel it")
    if not request.scan_dir:
        raise MapRunError("choose the scan folder to map")
    scan_dir = os.path.abspath(bpy.path.abspath(request.scan_dir))
    if not os.path.isdir(scan_dir):
        raise MapRunError(f"scan folder '{request.scan_dir}' does not exist")
    output_dir = (os.path.abspath(bpy.path.abspath(request.output_dir)) if request.output_dir
                  else os.path.normpath(scan_dir) + "_shine")
    command = _build_command(shine, replace(request, scan_dir=scan_dir), output_dir)
    print(f"ShineVDB: running {shlex.join(command)}")
    try:
        job = MapJob(command)
    except OSError as error:
        raise MapRunError(f"cannot start '{shine}': {error}") from None
    _run = MapRun(job=job, output_dir=output_dir, scene_name=scene.name,
                  view_layer_name=view_layer.name)
    _set_progress(0.0)
    if not bpy.app.timers.is_registered(step):
        # Persistent: the run goes on, and is imported, even if another .blend file is opened.
        bpy.app.timers.register(step, first_interval=POLL_INTERVAL_S, persistent=True)
    return _run


def step() -> Optional[float]:
    """Timer callback: takes in the job's output; finishes the run once the job has ended.

    Returns the delay until the next call, or None when the run is over (which ends the timer).
    """
    run = _run
    if run is None or run.state != "running":
        return None
    if run.job.poll():
        if run.job.progress is not None:
            _set_progress(run.job.progress.fraction)
        _redraw()
        return POLL_INTERVAL_S
    _finish(run)
    _redraw()
    return None


def cancel() -> None:
    """Stops the running job; :func:`step` then marks the run cancelled."""
    if is_running():
        _run.job.cancel()


def wait_until_done(timeout_s: float) -> MapRun:
    """Runs :func:`step` until the current run is over (for background scripts and tests).

    Raises:
        TimeoutError: the run is still going after ``timeout_s``.
    """
    deadline = time.monotonic() + timeout_s
    while is_running():
        if time.monotonic() > deadline:
            raise TimeoutError(f"shine map still running after {timeout_s:.0f} s")
        if step() is not None:
            time.sleep(POLL_INTERVAL_S)
    return _run


def _finish(run: MapRun) -> None:
    """Records how the job ended and imports its surface when it succeeded."""
    run.summary = list(run.job.stdout_lines)
    if not run.job.succeeded:
        run.state = "cancelled" if run.job.cancelled else "failed"
        run.error = run.job.error_message()
        if run.state == "failed":
            _notify_failure(run.error)
        return
    _set_progress(1.0)
    surface_path = os.path.join(run.output_dir, SURFACE_FILE)
    scene = bpy.data.scenes.get(run.scene_name)
    view_layer = scene.view_layers.get(run.view_layer_name) if scene is not None else None
    messages: List[level_set_import.Message] = []
    try:
        if view_layer is None:
            raise level_set_import.LevelSetImportError(
                f"scene '{run.scene_name}' or its view layer was removed; import "
                f"'{surface_path}' with File › Import")
        mesh_object = level_set_import.import_level_set(
            surface_path,
            collection=view_layer.active_layer_collection.collection,
            view_layer=view_layer,
            messages=messages,
        )
    except level_set_import.LevelSetImportError as error:
        run.state = "failed"
        run.error = f"mapping succeeded but the import failed: {error}"
        _notify_failure(run.error)
        return
    run.state = "done"
    run.imported_object = mesh_object.name
    run.summary.append(f"imported '{mesh_object.name}' from {surface_path}")
    for level, text in messages:  # colours and intensity, or why there are none
        run.summary.append(f"warning: {text}" if level == "WARNING" else text)
        if level == "WARNING":
            print(f"ShineVDB: {text}", file=sys.stderr)


def _set_progress(fraction: float) -> None:
    """Shows the current stage's progress on the panel's bar."""
    bpy.context.window_manager.shinevdb_progress = 100.0 * fraction


def _redraw() -> None:
    """Redraws the 3D views (the panel), which do not notice the timer's changes by themselves."""
    for window in bpy.context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


def _notify_failure(message: str) -> None:
    """Prints the error and, with a user interface, pops it up (it also stays on the panel)."""
    print(f"ShineVDB: mapping failed: {message}", file=sys.stderr)
    if bpy.app.background:  # no interface to pop up in (and popup_menu would crash)
        return
    window_manager = bpy.context.window_manager

    def draw(menu, _context):
        for line in textwrap.wrap(message, 90):
            menu.layout.label(text=line)

    with bpy.context.temp_override(window=window_manager.windows[0]):
        window_manager.popup_menu(draw, title="ShineVDB mapping failed", icon="ERROR")


def register():
    bpy.types.WindowManager.shinevdb_progress = FloatProperty(
        name="Progress",
        description="Progress of the current stage of the shine map run",
        subtype="PERCENTAGE",
        min=0.0,
        max=100.0,
        options={"SKIP_SAVE"},
    )


def unregister():
    """Stops a running job (its output would have nowhere to go) and the timer."""
    global _run
    if is_running():
        _run.job.cancel()
    if bpy.app.timers.is_registered(step):
        bpy.app.timers.unregister(step)
    _run = None
    del bpy.types.WindowManager.shinevdb_progress
