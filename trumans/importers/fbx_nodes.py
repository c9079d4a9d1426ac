"""FBX files as a tree of nodes: the ASCII (6.x / 7.x) and binary (node-record) encodings.

Both encodings hold the same structure: a node has a name, a list of property values and child
nodes. ``read_fbx_nodes`` returns the top-level nodes of either kind of file; ``trumans.importers.fbx``
interprets them (models, connections, animation curves).

Binary layout (FBX 6.1 / 7.x, "Kaydara FBX Binary" header): each node record is
``end_offset, num_properties, property_list_len, name_len`` (uint32, or uint64 from version 7500),
the name, the properties (a type code + data: ``Y C I F D L`` scalars, ``S R`` length-prefixed
bytes, ``f d l i b`` arrays with ``length, encoding (1 = zlib), compressed_length``), then the
child records and a null record. Strings ``"name\\x00\\x01Class"`` are read as ``"Class::name"``,
the form the ASCII files use.
"""
from __future__ import annotations

import re
import struct
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from trumans.input_files import check_input_file

__all__ = ["FbxNode", "read_fbx_nodes", "parse_ascii", "parse_binary", "BINARY_MAGIC"]

BINARY_MAGIC = b"Kaydara FBX Binary  \x00"


@dataclass
class FbxNode:
    """One FBX node: ``name``, its property values (str / int / float / numpy array) and children."""

    name: str
    props: list = field(default_factory=list)
    children: list["FbxNode"] = field(default_factory=list)

    def find(self, name: str) -> "FbxNode | None":
        """The first child called ``name`` (None if there is none)."""
        return next((c for c in self.children if c.name == name), None)

    def find_all(self, name: str) -> list["FbxNode"]:
        return [c for c in self.children if c.name == name]


def read_fbx_nodes(path: str | Path) -> tuple[list[FbxNode], int, bool]:
    """Top-level nodes of an FBX file, its version (e.g. 6100, 7400) and whether it is binary.

    Raises FileNotFoundError for a missing path and ValueError (naming the file) for a folder, FIFO
    or device, or a file that is neither encoding or is truncated."""
    path = check_input_file(path, "FBX file", "pass the path of a .fbx file")
    data = path.read_bytes()
    try:
        if data.startswith(BINARY_MAGIC):
            nodes, version = parse_binary(data)
            return nodes, version, True
        nodes = parse_ascii(data.decode("utf-8", errors="replace"))
    except ValueError as e:
        raise ValueError(f"{path}: {e}") from None
    return nodes, _ascii_version(nodes, path), False


def _ascii_version(nodes: list[FbxNode], path: Path) -> int:
    head = next((n for n in nodes if n.name == "FBXHeaderExtension"), None)
    v = head.find("FBXVersion") if head is not None else None
    if v is None or not v.props:
        raise ValueError(f"{path} is not an FBX file: no FBXHeaderExtension/FBXVersion (binary files start "
                         "with 'Kaydara FBX Binary')")
    return int(v.props[0])


# ------------------------------------------------------------------------------------------ ASCII

_KEY_RE = re.compile(r"^([A-Za-z_][\w|]*)\s*:(.*)$")
_VALUE_RE = re.compile(r'"((?:[^"\\]|\\.)*)"|([^,\s"]+)')
_NUM_RE = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def _value(tok: str):
    if _NUM_RE.match(tok):
        return int(tok) if tok.lstrip("+-").isdigit() else float(tok)
    return tok


def _values(text: str) -> list:
    """Comma-separated values of one node: quoted strings stay strings, numbers become int/float,
    bare words (``L``, ``Y``, ``*151``) stay strings. All-numeric lists become a float64 array."""
    text = text.strip()
    if not text:
        return []
    if '"' not in text and not re.search(r"[A-DF-Za-df-z_*]", text):  # numbers only (e/E allowed)
        parts = [p for p in text.replace("\n", ",").split(",") if p.strip()]
        if len(parts) > 8:
            return [np.array(parts, dtype=np.float64)]
        return [_value(p.strip()) for p in parts]
    out = []
    for m in _VALUE_RE.finditer(text):
        out.append(m.group(1) if m.group(1) is not None else _value(m.group(2)))
    return out


def parse_ascii(text: str) -> list[FbxNode]:
    """Parse ASCII FBX (6.x or 7.x). Values may continue over several lines (6.1 ``Key:`` lists);
    7.x arrays ``Name: *N { a: v, v, ... }`` become one array property."""
    root = FbxNode("")
    stack = [root]
    raw: dict[int, list[str]] = {}
    last: FbxNode | None = None
    for line in text.splitlines():
        s = line.strip()
        if not s or s.startswith(";"):
            continue
        if s == "}":
            if len(stack) == 1:
                raise ValueError("unbalanced '}' in the ASCII FBX")
            _finish(stack.pop(), raw)
            last = None
            continue
        m = _KEY_RE.match(s)
        if m is None:  # continuation of the previous node's values
            if last is None:
                raise ValueError(f"value line {s[:40]!r} follows no node")
            opens = s.endswith("{")
            raw[id(last)].append(s[:-1] if opens else s)
            if opens:
                stack.append(last)
                last = None
            continue
        name, rest = m.group(1), m.group(2).strip()
        node = FbxNode(name)
        stack[-1].children.append(node)
        opens = rest.endswith("{")
        raw[id(node)] = [rest[:-1] if opens else rest]
        if opens:
            stack.append(node)
            last = None
        else:
            last = node  # its values may continue on the next lines
    if len(stack) != 1:
        raise ValueError(f"{len(stack) - 1} unclosed '{{' at the end; the ASCII FBX is truncated")
    _finish(root, raw)
    return root.children


def _finish(node: FbxNode, raw: dict[int, list[str]]) -> None:
    """Parse a closed node's values; fold a 7.x array child ``a:`` into its parent's properties."""
    if id(node) in raw:
        node.props = _values(" ".join(raw.pop(id(node))))
    for c in node.children:
        if id(c) in raw:
            c.props = _values(" ".join(raw.pop(id(c))))
    if len(node.props) == 1 and isinstance(node.props[0], str) and node.props[0].startswith("*"):
        a = node.find("a")
        vals = a.props if a is not None else []
        arr = vals[0] if len(vals) == 1 and isinstance(vals[0], np.ndarray) else np.asarray(vals, np.float64)
        node.props = [np.atleast_1d(arr)]
        node.children = [c for c in node.children if c.name != "a"]


# ----------------------------------------------------------------------------------------- binary

_SCALAR = {b"Y": "<h", b"C": "<B", b"I": "<i", b"F": "<f", b"D": "<d", b"L": "<q"}
_ARRAY = {b"f": np.float32, b"d": np.float64, b"l": np.int64, b"i": np.int32, b"b": np.bool_}


def parse_binary(data: bytes) -> tuple[list[FbxNode], int]:
    """Parse binary FBX bytes: (top-level nodes, version)."""
    if len(data) < 27 or not data.startswith(BINARY_MAGIC):
        raise ValueError("not a binary FBX (the 'Kaydara FBX Binary' header is missing)")
    (version,) = struct.unpack_from("<I", data, 23)
    wide = version >= 7500
    nodes: list[FbxNode] = []
    pos = 27
    while True:
        node, pos = _read_node(data, pos, wide)
        if node is None:
            break
        nodes.append(node)
    return nodes, int(version)


def _read_node(data: bytes, pos: int, wide: bool) -> tuple[FbxNode | None, int]:
    head = "<QQQB" if wide else "<IIIB"
    size = struct.calcsize(head)
    if pos + size > len(data):
        raise ValueError(f"node record at byte {pos} runs past the end of the file; the binary FBX is truncated")
    end, n_props, _plen, name_len = struct.unpack_from(head, data, pos)
    if end == 0:  # null record: end of a node list
        return None, pos + size
    if end > len(data) or end <= pos:
        raise ValueError(f"node record at byte {pos} ends at {end}, outside the file ({len(data)} bytes); "
                         "the binary FBX is truncated or corrupt")
    pos += size
    name = data[pos:pos + name_len].decode("utf-8", errors="replace")
    pos += name_len
    props = []
    for _ in range(n_props):
        val, pos = _read_prop(data, pos)
        props.append(val)
    node = FbxNode(name, props)
    while pos < end:
        child, pos = _read_node(data, pos, wide)
        if child is None:
            break
        node.children.append(child)
    return node, end


MAX_ARRAY_BYTES = 1 << 30  # one array property of a binary FBX: 1 GiB (a long take's keys are a few MiB)
_ZLIB_MAX_RATIO = 1032  # zlib's largest possible inflation ratio


def _read_prop(data: bytes, pos: int):
    code = data[pos:pos + 1]
    pos += 1
    if code in _SCALAR:
        fmt = _SCALAR[code]
        (v,) = struct.unpack_from(fmt, data, pos)
        if code == b"C":  # a bool (0 / 1), or a character (6.1 key interpolation letters 'L', 'U', 's' ...)
            v = bool(v) if v in (0, 1) else chr(v)
        return v, pos + struct.calcsize(fmt)
    if code in _ARRAY:
        n, enc, clen = struct.unpack_from("<III", data, pos)
        pos += 12
        raw = data[pos:pos + clen]
        size = n * np.dtype(_ARRAY[code]).itemsize  # bytes the array declares
        if size > MAX_ARRAY_BYTES or (enc == 1 and size > _ZLIB_MAX_RATIO * len(raw) + 64):
            raise ValueError(f"array property at byte {pos} declares {n} values ({size / 2**20:.4g} MiB) from "
                             f"{len(raw)} stored bytes, more than zlib can hold or the {MAX_ARRAY_BYTES >> 20} MiB "
                             f"limit; the binary FBX is corrupt")
        if enc == 1:
            try:
                raw = zlib.decompressobj().decompress(raw, size)  # never inflates past the declared size
            except zlib.error as e:
                raise ValueError(f"array property at byte {pos} does not inflate ({e}); the binary FBX is corrupt") from None
        elif enc != 0:
            raise ValueError(f"array property at byte {pos} has unknown encoding {enc} (0 = raw, 1 = zlib)")
        if len(raw) < size:
            raise ValueError(f"array property at byte {pos} holds {len(raw)} of its {size} bytes; the binary FBX is "
                             f"truncated or corrupt")
        arr = np.frombuffer(raw, dtype=_ARRAY[code], count=n).copy()
        return arr, pos + clen
    if code in (b"S", b"R"):
        (n,) = struct.unpack_from("<I", data, pos)
        raw = data[pos + 4:pos + 4 + n]
        pos += 4 + n
        if code == b"R":
            return raw, pos
        s = raw.decode("utf-8", errors="replace")
        if "\x00\x01" in s:  # "name\x00\x01Class" -> "Class::name"
            nm, cls = s.split("\x00\x01", 1)
            s = f"{cls}::{nm}"
        return s, pos
    raise ValueError(f"unknown property type {code!r} at byte {pos - 1}; the binary FBX is corrupt")
