"""Small helpers shared by the panel sections (no classes to register)."""
from ..core.errors import ILError


def open_built_scene(op, context, build):
    """Run ``build()`` (returns a new scene); give it the user's settings, show it, report.

    Returns ``(operator result, scene or None)``; a failed build is reported and cancelled.
    """
    try:
        scene = build()
    except ILError as e:
        op.report({"ERROR"}, str(e))
        return {"CANCELLED"}, None
    copy_settings(context.scene, scene)
    if context.window is not None:
        context.window.scene = scene
    op.report({"INFO"}, f"Built scene '{scene.name}'")
    return {"FINISHED"}, scene


def copy_settings(src, dst):
    """Copy every section of ``src.illumination`` to ``dst.illumination`` (a scene a builder just made).

    A built scene then keeps the user's choices (output folders, sizes, methods) instead of the
    defaults; values never set stay unset, and the "last_*" result fields are not copied.
    """
    _copy_group(src.illumination, dst.illumination)


def _copy_group(a, b):
    for prop in a.bl_rna.properties:
        key = prop.identifier
        if key == "rna_type" or key.startswith("last_") or prop.type == "COLLECTION":
            continue
        if prop.type == "POINTER":
            _copy_group(getattr(a, key), getattr(b, key))
        elif not prop.is_readonly:
            if a.is_property_set(key):
                setattr(b, key, getattr(a, key))
            else:
                b.property_unset(key)
