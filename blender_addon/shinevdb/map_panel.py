"""3D view sidebar › ShineVDB: map a scan folder with ``shine map`` and import the result.

The settings live on the scene (saved with the .blend file); the run itself is in
:mod:`.map_run`. The panel shows the running stage with a progress bar, then either what
``shine`` printed and the imported object, or the error.
"""

import textwrap

import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from . import map_run
from .preferences import ShineNotFoundError, addon_preferences, resolve_shine_executable

# For wrapping long texts: average width of a character of the interface font at scale 1, and
# the room a label's margins and icon take.
_CHAR_WIDTH_PX = 7.5
_LABEL_MARGIN_PX = 60


class ShineMapSettings(bpy.types.PropertyGroup):
    """The ``shine map`` options the panel offers."""

    scan_dir: StringProperty(
        name="Scans",
        description="Scan folder: KITTI layout (velodyne/*.bin, poses.txt) or .ply/.pcd scans "
        "with poses",
        subtype="DIR_PATH",
    )
    output_dir: StringProperty(
        name="Output",
        description="Folder for map.vdb, surface.vdb, mesh.ply and stats.json; empty: the scan "
        "folder's path with '_shine' appended",
        subtype="DIR_PATH",
    )
    leaf_size_m: FloatProperty(
        name="Leaf Size",
        description="Size of the finest map cells; the surface voxels are half of it",
        default=0.2,
        min=0.01,
        soft_max=2.0,
        unit="LENGTH",
    )
    mode: EnumProperty(
        name="Mode",
        items=(
            ("batch", "Batch", "Train on all scans together"),
            ("incremental", "Incremental", "Train scan by scan (if this shine supports it)"),
        ),
        default="batch",
    )
    iterations: IntProperty(
        name="Iterations",
        description="Optimisation steps; 0: shine's default",
        default=0,
        min=0,
    )
    extra_args: StringProperty(
        name="Extra Arguments",
        description="More 'shine map' options, e.g. --no-eval --threads 4",
    )

    def request(self) -> map_run.MapRequest:
        return map_run.MapRequest(
            scan_dir=self.scan_dir,
            output_dir=self.output_dir,
            leaf_size_m=self.leaf_size_m,
            mode=self.mode,
            iterations=self.iterations,
            extra_args=self.extra_args,
        )


class SHINEVDB_OT_run_map(bpy.types.Operator):
    """Map the scan folder with shine map in the background and import the surface when done"""

    bl_idname = "shinevdb.run_map"
    bl_label = "Map Scans"

    @classmethod
    def poll(cls, context):
        return not map_run.is_running()

    def execute(self, context):
        try:
            shine = resolve_shine_executable(addon_preferences(context).shine_path)
            map_run.start(shine, context.scene.shinevdb_map.request(), context.scene,
                          context.view_layer)
        except (ShineNotFoundError, map_run.MapRunError) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        return {"FINISHED"}


class SHINEVDB_OT_cancel_map(bpy.types.Operator):
    """Stop the running shine map"""

    bl_idname = "shinevdb.cancel_map"
    bl_label = "Cancel"

    @classmethod
    def poll(cls, context):
        return map_run.is_running()

    def execute(self, context):
        map_run.cancel()
        return {"FINISHED"}


class VIEW3D_PT_shinevdb_map(bpy.types.Panel):
    """Sidebar panel: settings, run/cancel, progress and outcome."""

    bl_label = "ShineVDB Mapping"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "ShineVDB"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.shinevdb_map
        column = layout.column()
        column.enabled = not map_run.is_running()
        for name in ("scan_dir", "output_dir", "leaf_size_m", "mode", "iterations", "extra_args"):
            column.prop(settings, name)

        run = map_run.current()
        if run is not None and run.state == "running":
            progress = run.job.progress
            row = layout.row()
            row.enabled = False  # a read-only bar
            row.prop(context.window_manager, "shinevdb_progress", slider=True,
                     text=f"{progress.stage} {progress.done}/{progress.total}" if progress
                     else "starting")
            if progress is not None:
                timing = f"{progress.seconds:.0f} s"
                if progress.eta_s is not None:
                    timing += f", about {progress.eta_s} s left"
                layout.label(text=f"{timing}  {progress.detail}".strip())
            layout.operator(SHINEVDB_OT_cancel_map.bl_idname, icon="CANCEL")
            return
        layout.operator(SHINEVDB_OT_run_map.bl_idname, icon="PLAY")
        if run is None:
            return
        box = layout.box()
        width_chars = max(20, int((context.region.width - _LABEL_MARGIN_PX)
                                  / (_CHAR_WIDTH_PX * context.preferences.system.ui_scale)))
        if run.state == "done":
            for line in run.summary:
                _wrapped_label(box, line, width_chars)
        else:
            box.alert = run.state == "failed"
            _wrapped_label(box, f"{run.state}: {run.error}", width_chars,
                           icon="ERROR" if run.state == "failed" else "INFO")


def _wrapped_label(layout: bpy.types.UILayout, text: str, width_chars: int,
                   icon: str = "NONE") -> None:
    """A long text as several labels of at most ``width_chars`` (a label shows one line)."""
    continuation_icon = "NONE" if icon == "NONE" else "BLANK1"  # keeps the lines aligned
    for index, line in enumerate(textwrap.wrap(text, width_chars) or [""]):
        layout.label(text=line, icon=icon if index == 0 else continuation_icon)


classes = (ShineMapSettings, SHINEVDB_OT_run_map, SHINEVDB_OT_cancel_map, VIEW3D_PT_shinevdb_map)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.shinevdb_map = PointerProperty(type=ShineMapSettings)


def unregister():
    del bpy.types.Scene.shinevdb_map
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
