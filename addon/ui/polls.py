"""Small composable poll checks; each explains itself through ``poll_message_set``."""
import bpy


def _fail(cls, message):
    cls.poll_message_set(message)
    return False


def object_mode(cls, context):
    """True in Object Mode."""
    return context.mode == "OBJECT" or _fail(cls, "Switch to Object Mode first")


def selected_meshes(cls, context):
    """True when at least one mesh object is selected."""
    if any(o.type == "MESH" for o in context.selected_objects):
        return True
    return _fail(cls, "Select at least one mesh object")


def has_scene(cls, context):
    """True when there is a scene to work on."""
    return context.scene is not None or _fail(cls, "No active scene")


def saved_or_absolute(cls, path):
    """True when ``path`` can be resolved to a folder (named; relative paths need a saved file)."""
    if not path.strip():
        return _fail(cls, "Choose an output folder")
    if path.startswith("//") and not bpy.data.filepath:
        return _fail(cls, "Save the file first, or choose an absolute output folder")
    return True
