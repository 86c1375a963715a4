"""Digests of Blender data a bake depends on: a struct's settings (a modifier's), a node tree's shading, a mesh."""
import bpy
import numpy as np

from .scene import attribute, face_starts

_DTYPES = {"FLOAT": np.float32, "INT": np.int32, "BOOLEAN": bool, "INT8": np.int32, "FLOAT_VECTOR": np.float32,
           "FLOAT2": np.float32, "INT32_2D": np.int32, "FLOAT_COLOR": np.float32, "BYTE_COLOR": np.float32}
_UNREAD = (".select_", ".uv_select_", ".hide_", ".vs.", ".es.", ".pn.")
"""Attributes no evaluation or check reads: Edit Mode's selection, hiding and UV pins."""


def _topology(h, me):
    h.update(repr((len(me.vertices), len(me.edges), len(me.loops), len(me.polygons))).encode())
    h.update(face_starts(me).tobytes())


def mesh_digest(h, me):
    """Feed mesh ``me`` to hash ``h``: its counts, faces' loop starts and every attribute but :data:`_UNREAD`. False
    when an attribute is of a kind not read here (``h`` then holds part of the mesh)."""
    _topology(h, me)
    for a in sorted(me.attributes, key=lambda a: a.name):
        if a.name.startswith(_UNREAD):
            continue
        dtype = _DTYPES.get(a.data_type)
        if dtype is None:
            return False
        h.update(f"{a.name}:{a.domain}:{a.data_type}".encode())
        h.update(attribute(me, a.name, dtype).tobytes())
    return True


_SHAPE = (("position", np.float32), (".edge_verts", np.int32), (".corner_vert", np.int32), (".corner_edge", np.int32))


def shape_digest(h, me):
    """Feed mesh ``me``'s shape to hash ``h``: its counts, faces' loop starts, positions, edges and corners (what its
    loop triangles, area and closed parts are made of; not its UVs, creases or colours)."""
    _topology(h, me)
    for name, dtype in _SHAPE:
        values = attribute(me, name, dtype)
        h.update(name.encode() + (b"-" if values is None else values.tobytes()))


def rna_digest(h, struct, layout=True, skip=()):
    """A modifier's type and every setting (objects and node groups it uses by name, a node group's tree) but those
    named in ``skip``; ``layout`` False: without the sub-panels opened in its panel (``open_*``)."""
    h.update(struct.bl_rna.identifier.encode())
    for prop in struct.bl_rna.properties:
        if prop.identifier in ("rna_type", "name", "is_override_data_editable", "show_expanded", "is_active",
                               "show_viewport", "show_in_editmode", "show_on_cage", "persistent_uid"):
            continue
        if prop.identifier in skip or (not layout and prop.identifier.startswith("open_")):
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
