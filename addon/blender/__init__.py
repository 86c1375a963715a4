"""Blender helpers shared by bake, lab and ui: scene building blocks and materials (bpy, no core logic)."""
