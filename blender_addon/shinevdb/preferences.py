"""Add-on preferences: where the ``shine`` executable is."""

import os
import shutil

import bpy
from bpy.props import StringProperty

_EXECUTABLE_NAME = "shine"


class ShineNotFoundError(Exception):
    """No usable ``shine`` executable; the message says where to set its path."""


class ShineVDBPreferences(bpy.types.AddonPreferences):
    """Edit › Preferences › Add-ons › ShineVDB."""

    bl_idname = __package__

    shine_path: StringProperty(
        name="shine Executable",
        description="Path to the ShineVDB command-line program; empty: 'shine' found on PATH",
        subtype="FILE_PATH",
        default="",
    )

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "shine_path")
        try:
            shine = resolve_shine_executable(self.shine_path)
            layout.label(text=f"Using {shine}", icon="CHECKMARK")
        except ShineNotFoundError as error:
            layout.label(text=str(error), icon="ERROR")


def addon_preferences(context: bpy.types.Context) -> ShineVDBPreferences:
    """This add-on's preferences."""
    return context.preferences.addons[__package__].preferences


def resolve_shine_executable(configured_path: str) -> str:
    """Returns the absolute path of the ``shine`` program to run.

    Args:
        configured_path: the preference; empty means ``shine`` on PATH.

    Raises:
        ShineNotFoundError: the configured file is missing or not executable, or no ``shine`` is
            on PATH.
    """
    where = "Edit › Preferences › Add-ons › ShineVDB"
    if configured_path:
        path = os.path.abspath(bpy.path.abspath(configured_path))
        if not os.path.isfile(path) or not os.access(path, os.X_OK):
            raise ShineNotFoundError(
                f"shine executable '{path}' does not exist or is not executable; fix it in {where}")
        return path
    found = shutil.which(_EXECUTABLE_NAME)
    if found is None:
        raise ShineNotFoundError(
            f"'{_EXECUTABLE_NAME}' is not on PATH; set the path of the shine executable in {where}")
    return os.path.abspath(found)


def register():
    bpy.utils.register_class(ShineVDBPreferences)


def unregister():
    bpy.utils.unregister_class(ShineVDBPreferences)
