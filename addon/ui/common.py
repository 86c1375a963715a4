"""Small helpers shared by the panel sections (no classes to register)."""
import warnings

from ..core.errors import ILError, ILWarning


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


def run_job(op, job):
    """Run ``job()`` at an operator's boundary; return ``(True, result)`` or ``(False, None)``.

    Every :class:`ILWarning` the job emits becomes a WARNING report; a domain error, a full disk or
    running out of memory becomes one ERROR report (the operator then returns CANCELLED). Anything
    else is a bug and keeps its traceback.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ILWarning)
        try:
            result, message = job(), None
        except ILError as e:
            message = str(e)
        except MemoryError:
            message = "out of memory: use smaller sizes or fewer samples"
        except OSError as e:
            message = f"{e.strerror or e}" + (f": {e.filename}" if e.filename else "")
    for w in caught:
        if issubclass(w.category, ILWarning):
            op.report({"WARNING"}, str(w.message))
    if message is not None:
        op.report({"ERROR"}, message)
        return False, None
    return True, result
