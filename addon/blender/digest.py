"""Digests of Blender data a bake depends on: a struct's settings (a modifier's), a node tree's shading."""
import bpy


def rna_digest(h, struct):
    """A modifier's type and every setting (objects and node groups it uses by name, a node group's tree)."""
    h.update(struct.bl_rna.identifier.encode())
    for prop in struct.bl_rna.properties:
        if prop.identifier in ("rna_type", "name", "is_override_data_editable", "show_expanded", "is_active",
                               "show_viewport", "show_in_editmode", "show_on_cage", "persistent_uid"):
            continue
        value = getattr(struct, prop.identifier, None)
        if hasattr(value, "name") and hasattr(value, "bl_rna"):
            h.update(f"{prop.identifier}={value.name}".encode())
            if isinstance(value, bpy.types.NodeTree):
                node_tree_digest(h, value)
        elif isinstance(value, (int, float, str, bool)) or value is None:
            h.update(f"{prop.identifier}={value!r}".encode())
        elif hasattr(value, "__len__") and not hasattr(value, "bl_rna"):
            try:
                h.update(f"{prop.identifier}={tuple(value)!r}".encode())
            except TypeError:
                pass


def node_tree_digest(h, tree):
    """Node types, their unlinked input values and the links of a node tree (what shades, not where nodes sit)."""
    if tree is None:
        h.update(b"-")
        return
    for n in sorted(tree.nodes, key=lambda n: n.name):
        h.update(f"{n.name}:{n.bl_idname}".encode())
        if getattr(n, "image", None) is not None:
            h.update(n.image.name.encode())
        for sock in n.inputs:
            value = getattr(sock, "default_value", None)
            if value is not None and not sock.is_linked:
                h.update(repr(tuple(value) if hasattr(value, "__len__") else value).encode())
    for link in tree.links:
        h.update(f"{link.from_node.name}.{link.from_socket.identifier}>{link.to_node.name}.{link.to_socket.identifier}"
                 .encode())
