"""Blender helpers shared by bake, lab and ui (bpy, no core logic): state (leave the user's file as it was),
render (the one Cycles / EEVEE setup, passes to numpy), scene building blocks, materials, compat, progress,
interrupt."""
