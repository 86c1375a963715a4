"""Node-group builders and light linking (bpy side of the shading models)."""
