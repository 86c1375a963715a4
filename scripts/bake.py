"""Bake AO and irradiance light maps with Cycles (CPU); the .blend on disk is never modified.

    python scripts/bake.py scene.blend --objects Floor --maps ao --target vertex --out out/maps --save-as baked.blend
                                           (a copy of the file with the "IL AO" colour attributes and Lightmap UVs)

    python scripts/bake.py scene.blend --objects Floor Box --maps ao irradiance --out out/maps
    blender -b scene.blend -P scripts/bake.py -- --objects Floor --maps ao --out out/maps --target-error 0.01
    python scripts/bake.py scene.blend --objects ... --out out/maps --shard 2/8     (one share of a farm job)
    python scripts/bake.py --merge out/maps                                        (join the shards' reports)
    python scripts/bake.py scene.blend --objects ... --out out/maps --jobs 2       (2 shard processes here)
"""
import os
import signal
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.core.errors import InputError
    if args.merge:
        from addon.bake.report import merge_reports
        result = merge_reports(os.path.abspath(args.merge))
        print(result.summary)
        print(f"report: {result.path}")
        return
    if not args.objects or not args.out:
        raise InputError("--objects and --out are required (or --merge DIR)")
    if args.save_as and ((args.jobs or 1) > 1 or args.shard):
        raise InputError("--save-as keeps this run's products in one copy: it does not go with --jobs or --shard")
    if args.jobs and args.jobs > 1:
        return run_jobs(args)
    import bpy
    from addon.bake import BakeOptions, bake_lightmaps
    options = _cli.options_from(BakeOptions, args)
    if args.save_as:
        options.force = True                   # maps found unchanged would be skipped: the copy needs them all
    save_as = check_save_as(args.save_as, bpy.data.filepath) if args.save_as else None
    objects = []
    for name in args.objects:
        obj = bpy.data.objects.get(name)
        if obj is None:
            raise InputError(f"no object named '{name}' in the file")
        objects.append(obj)
    result = bake_lightmaps(objects, options.maps, os.path.abspath(args.out), options, scene=bpy.context.scene)
    for obj, maps in result["objects"].items():
        for m, e in maps.items():
            err = e["estimated_error"]
            err = "n/a" if err is None else f"{err:.4g}"
            kind = e["error_estimate"].split(":")[0] + (", before denoising" if e.get("denoised") else "")
            print(f"{obj} {m}: {e['file']} {e['resolution'][0]}x{e['resolution'][1]} "
                  f"{e['samples']} samples {e['seconds']:.2f} s est. error {err} ({kind})")
    print(result.summary)
    print(f"report: {result.path}")
    if save_as:
        save_copy(save_as)
        print(f"saved a copy: {save_as}")
    if result.get("failed"):
        from addon.core.errors import ILError
        raise ILError(f"{len(result['failed'])} object(s) failed, the others are baked: "
                      + "; ".join(f"{n}: {why}" for n, why in result["failed"].items()))


def check_save_as(path, opened):
    """The absolute path of ``--save-as``: a .blend whose folder exists, never the opened file (InputError)."""
    from addon.core.errors import InputError
    path = os.path.abspath(path)
    if not path.lower().endswith(".blend"):
        raise InputError(f"--save-as: not a .blend file name: {path}")
    if not os.path.isdir(os.path.dirname(path)):
        raise InputError(f"--save-as: no such folder: {os.path.dirname(path)}")
    same = opened and (os.path.realpath(path) == os.path.realpath(opened)
                       or (os.path.exists(path) and os.path.samefile(path, opened)))
    if same:
        raise InputError(f"--save-as: {path} is the opened file, which a bake never writes: name a copy")
    return path


def save_copy(path):
    """Save the session (baked colour attributes and generated light-map layers kept) as a copy at ``path``:
    written beside it under a temporary name and moved into place, so ``path`` is whole or untouched; the opened
    file and the session's file path are left as they were."""
    import bpy
    from addon.blender import interrupt
    from addon.core.errors import ILError
    tmp = os.path.join(os.path.dirname(path), f".{os.path.basename(path)}.{os.getpid()}.tmp.blend")
    try:
        with interrupt.blender_call():      # Blender's "Info: Saved copy as ..." kept off stdout (blender.chatter)
            result = bpy.ops.wm.save_as_mainfile(filepath=tmp, copy=True, check_existing=False, compress=False)
        if "FINISHED" not in result:
            raise ILError(f"--save-as: Blender did not save {path} ({', '.join(result)})")
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


def run_jobs(args):
    """Run ``--jobs J`` shard processes of this script at once (shards 1/J .. J/J), then merge their reports."""
    import bpy
    from addon.bake.report import merge_reports
    from addon.core.errors import ILError
    argv = _cli.script_argv()
    rest, skip = [], False
    for i, a in enumerate(argv):
        if skip:
            skip = False
            continue
        if a == "--jobs":
            skip = True
            continue
        if a.startswith("--jobs="):
            continue
        rest.append(a)
    script = os.path.abspath(__file__)
    if args.blend:
        rest.remove(args.blend)
    blend = os.path.abspath(args.blend) if args.blend else bpy.data.filepath
    if not blend:
        raise ILError("--jobs needs a saved .blend file (the shard processes open it)")
    inside = _cli._inside_blender()
    procs = []
    for k in range(1, args.jobs + 1):
        shard = ["--shard", f"{k}/{args.jobs}"]
        cmd = ([bpy.app.binary_path, "-b", blend, "-P", script, "--"] + rest + shard if inside
               else [sys.executable, script, blend] + rest + shard)
        procs.append(subprocess.Popen(cmd))
    codes = wait_for_shards(procs)
    result = merge_reports(os.path.abspath(args.out))
    print(result.summary)
    print(f"report: {result.path}")
    failed = [f"{k + 1}/{args.jobs} (exit {c})" for k, c in enumerate(codes) if c]
    if failed:
        raise ILError("shard(s) failed: " + ", ".join(failed))


#: Seconds the shard processes get to stop after Ctrl-C or SIGTERM before they are killed (their maps are
#: written atomically, so a killed shard leaves finished maps and no partial file).
SHARD_GRACE = 15


def wait_for_shards(procs):
    """Wait for the shard processes; on Ctrl-C or SIGTERM pass SIGINT on to them, wait for them to stop
    (killing those still running after SHARD_GRACE seconds) and raise KeyboardInterrupt."""
    def stop(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        return [p.wait() for p in procs]
    except KeyboardInterrupt:
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        deadline = time.monotonic() + SHARD_GRACE
        for p in procs:
            try:
                p.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        raise
    finally:
        signal.signal(signal.SIGTERM, previous)


def build_parser():
    from addon.bake.options import BakeOptions
    p = _cli.parser("bake.py", "Bake ambient-occlusion and irradiance light maps with Cycles on the CPU.")
    p.add_argument("--objects", nargs="+", metavar="NAME", help="mesh objects to bake (required unless --merge)")
    p.add_argument("--out", help="output folder (required unless --merge)")
    p.add_argument("--merge", metavar="DIR", help="join the shard reports in DIR into DIR/bake_report.json and stop")
    p.add_argument("--save-as", metavar="COPY.blend",
                   help="after the bake, save a copy of the file with the baked colour attributes (--target vertex) "
                        "and generated light-map UV layers; the opened .blend is never written")
    p.add_argument("--jobs", type=_cli.number(int, 1, 256), metavar="J",
                   help="run J shard processes of this bake at once here and merge their reports")
    return _cli.add_options(p, BakeOptions)


if __name__ == "__main__":
    _cli.run(build_parser(), main)
