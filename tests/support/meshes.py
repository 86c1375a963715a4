"""Meshes for tests: a primitive operator's object, and the same without the UV layers the operator gives it."""
import bpy


def added(op, **kw):
    """The object primitive operator ``op`` adds (with ``kw``), left unselected."""
    op(**kw)
    obj = bpy.context.object
    obj.select_set(False)
    return obj


def plain(obj):
    """``obj`` without the UV layers its primitive operator gave it: its layout is then an unwrapper's (a mesh's own
    layers may give it, unwrap._Copies.try_own_layers)."""
    while obj.data.uv_layers:
        obj.data.uv_layers.remove(obj.data.uv_layers[0])
    return obj
