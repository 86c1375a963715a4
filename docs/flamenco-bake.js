// Flamenco 3 job type: light maps of a level in N shards (scripts/bake.py --shard K/N), then one merge task.
// Put it in the Manager's scripts/ folder; the workers need Blender, this repository and the shared storage.
const JOB_TYPE = {
    label: "Illumination Lab light maps",
    settings: [
        { key: "blendfile", type: "string", subtype: "file_path", required: true, description: "scene .blend" },
        { key: "objects", type: "string", required: true, description: "mesh objects, separated by ; (names may hold spaces)" },
        { key: "out", type: "string", subtype: "dir_path", required: true, description: "output folder" },
        { key: "args", type: "string", default: "--maps ao irradiance --texel-density 32 --samples 64",
          description: "other scripts/bake.py options" },
        { key: "shards", type: "int32", default: 8, description: "tasks (N)" },
        { key: "script", type: "string", required: true, description: "path of scripts/bake.py on the workers" },
    ],
};

function compileJob(job) {
    const s = job.settings;
    const bakes = [];
    for (let k = 1; k <= s.shards; k++) {
        const task = author.Task(`bake ${k}/${s.shards}`, "blender");
        task.addCommand(author.Command("blender-render", {
            exe: "{blender}", exeArgs: "{blenderArgs}", blendfile: s.blendfile,
            args: ["-P", s.script, "--", "--objects", ...s.objects.split(";").map((n) => n.trim()).filter(Boolean),
                   ...s.args.split(/\s+/).filter(Boolean),
                   "--out", s.out, "--overwrite", "--shard", `${k}/${s.shards}`],
        }));
        job.addTask(task);
        bakes.push(task);
    }
    const merge = author.Task("merge reports", "blender");
    merge.addCommand(author.Command("blender-render", {
        exe: "{blender}", exeArgs: "{blenderArgs}", blendfile: s.blendfile,
        args: ["-P", s.script, "--", "--merge", s.out],
    }));
    for (const t of bakes) merge.addDependency(t);
    job.addTask(merge);
}
