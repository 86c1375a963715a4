"""The operator boundary, in one place (as glTF-Blender-IO does it): a job runs, its ILWarnings become
WARNING reports, a domain error, a full disk or running out of memory one ERROR report and CANCELLED.

``class IL_OT_x(JobOperator, bpy.types.Operator)`` implements ``job(context)`` (returns a
core.result.JobResult, whose ``summary`` is reported) and may implement ``finished(context, result)``
(store figures for the panel). Operators that build a scene call :func:`open_built_scene`.
"""
import warnings

from ..core.errors import OUT_OF_MEMORY, ILError, ILWarning, os_error_message


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


class JobOperator:
    """Mixin for the operators that run a job (see the module docstring)."""

    def job(self, context):
        raise NotImplementedError

    def finished(self, context, result):
        """Called after a successful job (the panel's figures); nothing by default."""

    def execute(self, context):
        ok, result = run_job(self, lambda: self.job(context))
        if not ok:
            return {"CANCELLED"}
        self.finished(context, result)
        if result is not None and result.summary:
            self.report({"INFO"}, result.summary)
        return {"FINISHED"}


class BuildSceneOperator:
    """Mixin for the operators that add a built-in scene: ``build(context)`` returns the new scene, which
    gets the user's settings and is shown (:func:`open_built_scene`); ``built(context, scene)`` may adjust
    it. The user's own scenes are not touched."""
    bl_options = {"REGISTER", "UNDO"}

    def build(self, context):
        raise NotImplementedError

    def built(self, context, scene):
        """Called with the new scene; nothing by default."""

    def execute(self, context):
        result, scene = open_built_scene(self, context, lambda: self.build(context))
        if scene is not None:
            self.built(context, scene)
        return result


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
            message = OUT_OF_MEMORY
        except OSError as e:
            message = os_error_message(e)
    for w in caught:
        if issubclass(w.category, ILWarning):
            op.report({"WARNING"}, str(w.message))
    if message is not None:
        op.report({"ERROR"}, message)
        return False, None
    return True, result
