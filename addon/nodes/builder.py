"""A small graph builder for shader node trees: math in Python, tidy frames and columns in the editor.

``g = Graph(tree)``; ``with g.block("D: Beckmann"):`` puts every node made inside into a
labelled frame; ``g.math("MULTIPLY", a, b)`` and friends take sockets or plain numbers
and return the output socket. ``g.layout()`` places nodes in columns by their distance
from the group input and gives each frame its own horizontal band, so a user who opens
the group reads it left to right, one term per frame.
"""
import contextlib

import bpy

COLUMN = 210
ROW = 175


def is_socket(x):
    return isinstance(x, bpy.types.NodeSocket)


class Graph:
    def __init__(self, tree):
        self.tree = tree
        self.nodes = tree.nodes
        self.links = tree.links
        self.frame = None
        self.blocks = [[]]
        self.frames = [None]
        self._zero = self._zero_v = None
        self._regs = {}

    # -- structure --------------------------------------------------------------------------------
    @contextlib.contextmanager
    def block(self, label):
        """Nodes made inside go into a frame labelled ``label``."""
        frame = self.nodes.new("NodeFrame")
        frame.label = label
        frame.name = label
        frame.label_size = 16
        frame.shrink = True
        saved = self.frame
        self.frame = frame
        self.frames.append(frame)
        self.blocks.append([])
        try:
            yield frame
        finally:
            self.frame = saved

    def node(self, bl_idname, label=None, **props):
        n = self.nodes.new(bl_idname)
        for key, value in props.items():
            setattr(n, key, value)
        if label:
            n.label = label
        if self.frame is not None:
            n.parent = self.frame
            self.blocks[self.frames.index(self.frame)].append(n)
        else:
            self.blocks[0].append(n)
        return n

    def feed(self, value, socket):
        """Link ``value`` into ``socket`` if it is a socket, else set it as the default value."""
        if value is None:
            return
        if is_socket(value):
            self.links.new(value, socket)
        elif hasattr(socket, "default_value"):
            current = socket.default_value
            if hasattr(current, "__len__") and not hasattr(value, "__len__"):
                value = [value] * len(current)
            socket.default_value = value

    # -- registers: constants loaded once per shading point ----------------------------------------
    def registers(self, geometry):
        """Set up :meth:`reg`: (0, 0, 0) = Normal - Normal of this Geometry node and 0 its dot product with
        itself (values Cycles cannot fold, so nodes built on them stay nodes, computed once per shading point
        and shared by every node group instance of the material)."""
        normal = geometry.outputs["Normal"]
        self._zero_v = self.vmath("SUBTRACT", normal, normal, label="(0, 0, 0) (register)")
        self._zero = self.dot(self._zero_v, self._zero_v, label="0 (register)")

    def reg(self, value, label=None):
        """``value`` (a number or a socket that is constant in practice) as the output of a node computed
        once per shading point. Cycles' SVM loads a constant operand before every node that takes it,
        which costs about as much as the operation; a linked operand costs nothing."""
        if not is_socket(value) and value == 0.0:
            return self._zero
        key = ("f", value if not is_socket(value) else value.as_pointer())
        if key not in self._regs:
            self._regs[key] = self.math("ADD", self._zero, value, label=label or f"{value:g}"
                                        if not is_socket(value) else label)
        return self._regs[key]

    def vreg(self, value, label=None):
        """A colour or vector ``value`` computed once per shading point (see :meth:`reg`)."""
        key = ("v", tuple(value) if not is_socket(value) else value.as_pointer())
        if key not in self._regs:
            self._regs[key] = self.vmath("ADD", self._zero_v, value, label=label)
        return self._regs[key]

    # -- arithmetic -------------------------------------------------------------------------------
    def math(self, op, a, b=None, c=None, clamp=False, label=None):
        n = self.node("ShaderNodeMath", label=label, operation=op, use_clamp=clamp)
        for i, x in enumerate((a, b, c)):
            self.feed(x, n.inputs[i])
        return n.outputs[0]

    def add(self, a, b, label=None):
        return self.math("ADD", a, b, label=label)

    def sub(self, a, b, label=None):
        return self.math("SUBTRACT", a, b, label=label)

    def mul(self, a, b, label=None):
        return self.math("MULTIPLY", a, b, label=label)

    def div(self, a, b, label=None):
        return self.math("DIVIDE", a, b, label=label)

    def max(self, a, b, label=None):
        return self.math("MAXIMUM", a, b, label=label)

    def min(self, a, b, label=None):
        return self.math("MINIMUM", a, b, label=label)

    def pow(self, a, b, label=None):
        return self.math("POWER", a, b, label=label)

    def gt(self, a, b, label=None):
        return self.math("GREATER_THAN", a, b, label=label)

    def madd(self, a, b, c, label=None):
        """a b + c in one node."""
        return self.math("MULTIPLY_ADD", a, b, c, label=label)

    @staticmethod
    def _by_id(sockets, identifier):
        return next(s for s in sockets if s.identifier == identifier)

    def lerp(self, a, b, t, label=None):
        """a (1 - t) + b t in one Mix node: with a constant t of 0 or 1 Cycles keeps only the chosen
        branch (constant folding), with a linked t both are evaluated. A switch fixed when the group is
        built (``t`` the number 0 or 1) is the chosen branch itself, no node."""
        if not is_socket(t) and t in (0.0, 1.0):
            return b if t else a
        n = self.node("ShaderNodeMix", label=label, data_type="FLOAT", clamp_factor=False)
        self.feed(t, self._by_id(n.inputs, "Factor_Float"))
        self.feed(a, self._by_id(n.inputs, "A_Float"))
        self.feed(b, self._by_id(n.inputs, "B_Float"))
        return self._by_id(n.outputs, "Result_Float")

    def add_scaled(self, a, b, t, label=None):
        """Colour a + t b in one Mix node (blend Add, factor not clamped)."""
        n = self.node("ShaderNodeMix", label=label, data_type="RGBA", blend_type="ADD", clamp_factor=False,
                      clamp_result=False)
        self.feed(t, self._by_id(n.inputs, "Factor_Float"))
        self.feed(a, self._by_id(n.inputs, "A_Color"))
        self.feed(b, self._by_id(n.inputs, "B_Color"))
        return self._by_id(n.outputs, "Result_Color")

    def vmath(self, op, a, b=None, c=None, scale=None, label=None):
        """Vector Math ``op`` of a, b, c (the third operand of MULTIPLY_ADD, ...)."""
        n = self.node("ShaderNodeVectorMath", label=label, operation=op)
        self.feed(a, n.inputs[0])
        if b is not None:
            self.feed(b, n.inputs[1])
        if c is not None:
            self.feed(c, n.inputs[2])
        if scale is not None:
            self.feed(scale, n.inputs["Scale"])
        out = "Value" if op in {"DOT_PRODUCT", "LENGTH", "DISTANCE"} else "Vector"
        return n.outputs[out]

    def dot(self, a, b, label=None):
        return self.vmath("DOT_PRODUCT", a, b, label=label)

    def normalize(self, a, label=None):
        return self.vmath("NORMALIZE", a, label=label)

    def scale(self, vec, s, label=None):
        return self.vmath("SCALE", vec, scale=s, label=label)

    def vadd(self, a, b, label=None):
        return self.vmath("ADD", a, b, label=label)

    def vmul(self, a, b, label=None):
        return self.vmath("MULTIPLY", a, b, label=label)

    def vlerp(self, a, b, t, label=None):
        return self.vadd(a, self.scale(self.vmath("SUBTRACT", b, a), t), label=label)

    def prune(self):
        """Remove every node the group output does not read (the unchosen branches of fixed switches)."""
        keep, todo = set(), [n for n in self.nodes if n.bl_idname == "NodeGroupOutput"]
        while todo:
            node = todo.pop()
            if node.name not in keep:
                keep.add(node.name)
                todo.extend(lk.from_node for s in node.inputs for lk in s.links)
        keep |= {n.name for n in self.nodes if n.bl_idname == "NodeGroupInput"}
        dead = [n for n in self.nodes if n.bl_idname != "NodeFrame" and n.name not in keep]
        dead_names = {n.name for n in dead}
        self.blocks = [[n for n in b if n.name not in dead_names] for b in self.blocks]
        for node in dead:
            self.nodes.remove(node)
        for k, frame in enumerate(self.frames):
            if frame is not None and not self.blocks[k]:
                self.nodes.remove(frame)
                self.frames[k] = None

    # -- layout -----------------------------------------------------------------------------------
    def layout(self, x0=0.0, y0=0.0):
        """Columns by depth from the sources, one horizontal band per frame."""
        depth = {}

        def d(node):
            if node.name in depth:
                return depth[node.name]
            depth[node.name] = 0
            parents = [lk.from_node for s in node.inputs for lk in s.links]
            depth[node.name] = 1 + max((d(p) for p in parents), default=-1)
            return depth[node.name]

        for n in self.nodes:
            if n.bl_idname != "NodeFrame":
                d(n)
        y = y0
        for frame, members in zip(self.frames, self.blocks):
            if not members:
                continue
            per_col = {}
            for n in members:
                col = depth[n.name]
                row = per_col.get(col, 0)
                per_col[col] = row + 1
                n.location = (x0 + col * COLUMN, y - row * ROW)
            y -= max(per_col.values()) * ROW + 90
        return y
