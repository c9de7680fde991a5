#!/usr/bin/env python3
"""Writes the hand-made seed corpus of tests/fuzz/corpus (run from anywhere; idempotent).

Seeds are small valid (and a few nearly valid) inputs of each format, so that the fuzzers start
from the accepted language rather than from nothing. The scene seeds also take the repo's
assets/scenes; trajectory seeds take the first lines of assets/trajectories.
"""
import json
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
CORPUS = os.path.join(HERE, "corpus")


def put(harness, name, data):
    d = os.path.join(CORPUS, harness)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


# ---------------------------------------------------------------- meshes: a tetrahedron, a square
TET_V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TET_F = [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)]


def stl_ascii(v, f):
    s = "solid tet\n"
    for t in f:
        s += "  facet normal 0 0 0\n    outer loop\n"
        for i in t:
            s += "      vertex %g %g %g\n" % v[i]
        s += "    endloop\n  endfacet\n"
    return s + "endsolid tet\n"


def stl_binary(v, f, header=b"binary stl"):
    out = header.ljust(80, b"\0") + struct.pack("<I", len(f))
    for t in f:
        out += struct.pack("<3f", 0, 0, 0)
        for i in t:
            out += struct.pack("<3f", *v[i])
        out += struct.pack("<H", 0)
    return out


put("stl", "tet_ascii.stl", stl_ascii(TET_V, TET_F))
put("stl", "tet_binary.stl", stl_binary(TET_V, TET_F))
# A binary file whose header starts with "solid" (the size decides).
put("stl", "tet_binary_solid_header.stl", stl_binary(TET_V, TET_F, b"solid but binary"))
put("stl", "empty_ascii.stl", "solid empty\nendsolid empty\n")
put("stl", "degenerate_facet.stl", stl_ascii(TET_V, [(0, 0, 1), (0, 1, 2)]))

obj = "# tet\n" + "".join("v %g %g %g\n" % p for p in TET_V)
obj += "".join("f %d %d %d\n" % tuple(i + 1 for i in t) for t in TET_F)
put("obj", "tet.obj", obj)
put("obj", "quad_slashes_negative.obj",
    "o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0 1\nv 0 1 0\nvt 0 0\nvn 0 0 1\n"
    "f 1/1/1 2/1/1 3//1 4\nf -4 -2 -1\ng x\ns off\nusemtl m\n")

def ply_header(fmt, nv, nf, vtype="float", count="uchar", index="int", extra=""):
    return ("ply\nformat %s 1.0\ncomment tet\nelement vertex %d\nproperty %s x\n"
            "property %s y\nproperty %s z\n%selement face %d\nproperty list %s %s vertex_indices\n"
            "end_header\n" % (fmt, nv, vtype, vtype, vtype, extra, nf, count, index))

ply = ply_header("ascii", 4, 4) + "".join("%g %g %g\n" % p for p in TET_V)
ply += "".join("3 %d %d %d\n" % t for t in TET_F)
put("ply", "tet_ascii.ply", ply)
b = ply_header("binary_little_endian", 4, 4, "double", "uchar", "uint").encode()
for p in TET_V:
    b += struct.pack("<3d", *p)
for t in TET_F:
    b += struct.pack("<B3I", 3, *t)
put("ply", "tet_binary.ply", b)
b = ply_header("binary_little_endian", 4, 1, "float", "int", "short",
               "property uchar red\n").encode()
for p in TET_V:
    b += struct.pack("<3fB", *p, 200)
b += struct.pack("<i4h", 4, 0, 1, 2, 3)
put("ply", "quad_binary_extra_property.ply", b)
put("ply", "extra_element.ply",
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    "property float z\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n"
    "element face 1\nproperty list uchar int vertex_index\nend_header\n"
    "0 0 0\n1 0 0\n0 1 0\n0 1\n3 0 1 2\n")

# ---------------------------------------------------------------- scenes
for name in sorted(os.listdir(os.path.join(ROOT, "assets", "scenes"))):
    with open(os.path.join(ROOT, "assets", "scenes", name), "rb") as f:
        content = f.read()
    # Version 2 documents are the document harness's; version 1 scenes seed both.
    if b'"version": 2' not in content:
        put("scene", name, content)
    put("document", name, content)
nodes = [
    {"type": "sphere", "radius": 0.05},
    {"type": "box", "size": [0.1, 0.2, 0.3]},
    {"type": "rounded_box", "size": [0.1, 0.1, 0.1], "radius": 0.01},
    {"type": "cylinder", "radius": 0.02, "height": 0.1},
    {"type": "capsule", "a": [0, 0, 0], "b": [0, 0, 0.1], "radius": 0.01},
    {"type": "cone", "radius_bottom": 0.05, "radius_top": 0.0, "height": 0.1},
    {"type": "torus", "major_radius": 0.05, "minor_radius": 0.01},
    {"type": "half_space", "normal": [0, 0, 1], "offset": 0.01},
    {"type": "extrusion", "profile": [[0, 0], [0.1, 0], [0, 0.1]], "height": 0.02},
]
kids = [{"type": "sphere", "radius": 0.05}, {"type": "box", "size": [0.05, 0.05, 0.05]}]
nodes += [
    {"type": "union", "children": kids},
    {"type": "intersection", "children": kids},
    {"type": "difference", "children": kids},
    {"type": "smooth_union", "radius": 0.01, "children": kids},
    {"type": "smooth_intersection", "radius": 0.01, "children": kids},
    {"type": "smooth_difference", "radius": 0.01, "children": kids},
    {"type": "offset", "distance": -0.01, "children": kids[:1]},
    {"type": "shell", "thickness": 0.002, "children": kids[:1]},
    {"type": "translate", "translation": [0.1, 0, 0], "children": kids},
    {"type": "rotate", "axis": [0, 0, 1], "angle": 0.5, "children": kids},
    {"type": "scale", "factors": [1, 2, 3], "children": kids[:1]},
    {"type": "scale", "factors": 2, "children": kids[:1]},
    {"type": "mirror", "normal": [1, 0, 0], "offset": 0.1, "keep_original": True,
     "children": kids[:1]},
    {"type": "linear_array", "step": [0.1, 0, 0], "count": 3, "children": kids[:1]},
    {"type": "polar_array", "axis": [0, 0, 1], "count": 4, "step_angle": 0.5,
     "children": kids[:1]},
]
solids = [{"name": "s%d" % i, "root": dict(n, id="n%d" % i, name=n["type"])}
          for i, n in enumerate(nodes)]
put("scene", "every_node.json", json.dumps(
    {"format": "spidarcad-scene", "version": 1, "units": "m", "description": "every node type",
     "solids": solids}, indent=1))
put("scene", "parts_snap.json", json.dumps(
    {"format": "spidarcad-scene", "version": 1, "solids": [
        {"name": "a", "root": kids[0]}, {"name": "b", "root": kids[1]}],
     "parts": [{"name": "base", "solid": "a", "kind": "fixed"},
               {"name": "peg", "solid": "b", "position": [0.1, 0, 0],
                "rotation": [1, 0, 0, 0],
                "seats": [{"on": "base", "position": [0, 0, 0.05], "rotation": [1, 0, 0, 0],
                           "position_tolerance": 0.002, "angle_tolerance": 0.1}]}],
     "snap": {"max_force": 1.0, "vertex_radius": 0.008, "edge_radius": 0.005,
              "face_radius": 0.003}}, indent=1))

# ---------------------------------------------------------------- clipboard
put("clipboard", "solid.json", json.dumps(
    {"format": "spidarcad-clipboard", "version": 1,
     "solid": {"name": "clay", "root": nodes[9]}}, indent=2))
put("clipboard", "node.json", json.dumps(
    {"format": "spidarcad-clipboard", "version": 1, "node": nodes[17]}))
put("clipboard", "bare_node.json", json.dumps(nodes[8]))
put("clipboard", "bare_solid.json", json.dumps({"name": "blob", "root": nodes[0]}))

# ---------------------------------------------------------------- trajectories
for name in sorted(os.listdir(os.path.join(ROOT, "assets", "trajectories"))):
    with open(os.path.join(ROOT, "assets", "trajectories", name)) as f:
        put("trajectory", name, "".join(f.readlines()[:12]))
put("trajectory", "comments_blanks.csv",
    "# t,x,y,z,qw,qx,qy,qz,grasp\n\n  0, 0,0,0, 1,0,0,0, 1.5707963267948966\r\n"
    "   # indented comment\n0.5,1e-3,-2e-3,0.01,0.7071067811865476,0,0,0.7071067811865476,0.5\n"
    "1e0,0,0,0,1,0,0,0,3.14\n")

# ---------------------------------------------------------------- fk / ik / tension batch lines
L = 0.3939543
put("fk_batch", "rest.csv", ",".join([str(L)] * 8) + "\n")
put("fk_batch", "mixed.csv", "# lengths\n%s\nnan,1,2,3,4,5,6,7\n0.3,0.4,0.35,0.38,0.41,0.3,0.33,0.4\n"
    "1,2,3\n  \n" % ",".join([str(L)] * 8))
put("ik_batch", "rest.csv", "0,0,0,0,0.04,0,0.04,0,0\n0,0,0.05,-0.04,0,0,0,0.04,0\n")
put("ik_batch", "mixed.csv", "# pose\n0.01,0.02,-0.03,0,0.04,0,0.04,0,0\nx,1\nNaN,0,0,0,0,0,0,0,0\n")
put("tension_batch", "rest.csv", "0,0,0,0,0.04,0,0.04,0,0,1,0,0,0,0,0,0\n"
    "0,0,0,0,0.04,0,0.04,0,0,0,0,-2,0.01,0,0,0.5\n")
put("tension_batch", "mixed.csv", "# request\n0.02,0.01,0,0,0.04,0,0.04,0,0,0,1,0,0,0,0.02,0\n"
    "nan,0,0,0,0.04,0,0.04,0,0,1,0,0,0,0,0,0\n")

# ---------------------------------------------------------------- USB packets
def crc16(data):
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


def packet(ptype, seq, payload):
    body = bytes([0x53, 0x47, 1, ptype]) + struct.pack("<I", seq) + payload
    body = body.ljust(62, b"\0")
    return body + struct.pack("<H", crc16(body))


hello = lambda seq, wd: packet(0x01, seq, struct.pack("<H", wd))
reply = lambda seq: packet(0x02, seq, struct.pack("<5H", 1, 20, 8000, 2048, 1000) + b"SIM-0001".ljust(16, b"\0"))
command = lambda seq, mn, flags: packet(0x10, seq, struct.pack("<8HB", *mn, flags))
state = lambda seq, t, counts, cseq, flags: packet(
    0x20, seq, struct.pack("<Q8iIBB", t, *counts, cseq, 0, flags))

# Board side: records of control byte + packet. Control 0: deliver as is; 0xC0: tick.
session = [(0, hello(1, 20)), (0, command(2, [500] * 8, 1)), (0xC0, bytes(64)),
           (0, command(3, [65535] * 8, 1)), (0, command(4, [100] * 8, 2)),
           (0, command(5, [100] * 8, 4 | 1)), (0xE0, bytes(64))]
put("usb_board", "session.bin", b"".join(bytes([c]) + p for c, p in session))
put("usb_board", "hello_only.bin", bytes([0]) + hello(7, 1))
# Control 0x13: frame + set type Hello?(type bits 0) + echo: the harness makes it valid.
put("usb_board", "framed_command.bin", bytes([0x01 | 0x02 | (2 << 2) | 0x10]) + bytes(64))
put("usb_board", "corrupt.bin", bytes([0]) + hello(1, 20)[:-1] + b"\0" + bytes([0xA0]) + hello(2, 5))

# Host side: the driver's Hello is sequence 1, its first Command sequence 2 (echo fills them).
host = [(0x10 | 0x01, reply(0))] + [(0x10 | 0x01, state(0, 1000 * k, [k] * 8, 0, 1))
                                    for k in range(1, 5)]
host += [(0xC0, bytes(64)), (0, state(9, 9000, [0] * 8, 2, 0)), (0xE0, bytes(64)),
         (0x10 | 0x01, reply(0)), (0x10 | 0x01, state(0, 1, [-5] * 8, 0, 0x0F))]
put("usb_host", "session.bin", b"".join(bytes([c]) + p for c, p in host))
put("usb_host", "wrong_version.bin", bytes([0]) + packet(0x02, 1, b"")[:2] + b"\x02" +
    packet(0x02, 1, b"")[3:])
put("usb_host", "reply_only.bin", bytes([0]) + reply(1))

# ---------------------------------------------------------------- VTU (ASCII; VTK's XML reader)
def vtu(points, cells, cell_type, regions=None):
    n = len(cells[0])
    s = ('<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="0.1" '
         'byte_order="LittleEndian">\n<UnstructuredGrid>\n<Piece NumberOfPoints="%d" '
         'NumberOfCells="%d">\n<Points>\n<DataArray type="Float64" NumberOfComponents="3" '
         'format="ascii">\n' % (len(points), len(cells)))
    s += "\n".join("%g %g %g" % p for p in points)
    s += '\n</DataArray>\n</Points>\n<Cells>\n<DataArray type="Int64" Name="connectivity" format="ascii">\n'
    s += "\n".join(" ".join(str(i) for i in c) for c in cells)
    s += '\n</DataArray>\n<DataArray type="Int64" Name="offsets" format="ascii">\n'
    s += " ".join(str(n * (k + 1)) for k in range(len(cells)))
    s += '\n</DataArray>\n<DataArray type="UInt8" Name="types" format="ascii">\n'
    s += " ".join(str(cell_type) for _ in cells)
    s += "\n</DataArray>\n</Cells>\n"
    if regions is not None:
        s += ('<CellData>\n<DataArray type="Int32" Name="region" format="ascii">\n%s\n'
              '</DataArray>\n</CellData>\n' % " ".join(str(r) for r in regions))
    return s + "</Piece>\n</UnstructuredGrid>\n</VTKFile>\n"

put("vtu", "tet.vtu", vtu(TET_V, [(0, 1, 2, 3)], 10, [1]))
put("vtu", "two_tets_flipped.vtu", vtu(TET_V + [(1, 1, 1)], [(0, 1, 2, 3), (1, 2, 3, 4)], 10))
mid = lambda a, b: tuple((TET_V[a][k] + TET_V[b][k]) / 2 for k in range(3))
quad = TET_V + [mid(0, 1), mid(1, 2), mid(0, 2), mid(0, 3), mid(1, 3), mid(2, 3)]
put("vtu", "quadratic_tet.vtu", vtu(quad, [tuple(range(10))], 24, [3]))

# ---------------------------------------------------------------- calibration files
CALIBRATION = {
    "format": "spidarcad-calibration", "version": 1,
    "device": {"kind": "simulated", "seed": 3, "frame": {"a": 0.24, "b": 0.24, "c": 0.24},
               "pole": 0.04},
    "date": "2026-12-02T01:45:03Z", "method": "self",
    "encoder": {"counts_per_rev": 2000, "pulley_radius": 0.008},
    "strings": [{"offset": 0.38 + 0.001 * i, "gain": 1.0 + 0.01 * i, "quadratic": -0.03,
                 "stretch": 0.0004} for i in range(8)],
    "fit": {"samples": 101, "iterations": 9, "condition": 640.5, "rms_residual": 1.3e-05,
            "string_rms_residual": [1.3e-05] * 8},
}
put("calibration_file", "self.json", json.dumps(CALIBRATION, indent=2))
usb = json.loads(json.dumps(CALIBRATION))
usb["device"] = {"kind": "usb", "serial": "SPG-0042", "frame": {"a": 0.3, "b": 0.25, "c": 0.2},
                 "pole": 0.05}
usb["method"] = "line"
put("calibration_file", "usb_line.json", json.dumps(usb))
short = json.loads(json.dumps(CALIBRATION))
short["strings"] = short["strings"][:7]
put("calibration_file", "seven_strings.json", json.dumps(short))

# ---------------------------------------------------------------- TetGen .node/.ele pairs
# One input holds both files: the .node text, a NUL byte, the .ele text (node_ele_fuzz.cc). The
# seed platform.node_ele is the pair `spidarcad mesh assets/scenes/platform.json --resolution 0.03
# --tets tetgen --out platform.node` wrote (joined by hand; it is not rewritten here).


def node_ele(nodes, eles):
    return nodes.encode() + b"\0" + eles.encode()


def node_text(points, first=0, attributes=0, markers=0):
    s = "%d 3 %d %d\n" % (len(points), attributes, markers)
    for i, p in enumerate(points):
        extra = " 7.5" * attributes + (" 1" if markers else "")
        s += "%d %r %r %r%s\n" % ((i + first,) + tuple(float(x) for x in p) + (extra,))
    return s


def ele_text(tets, first=0, per=4, region=None):
    s = "%d %d %d\n" % (len(tets), per, 0 if region is None else 1)
    for i, t in enumerate(tets):
        s += "%d %s%s\n" % (i + first, " ".join(str(n + first) for n in t),
                            "" if region is None else " %d" % region)
    return s


put("node_ele", "tet_0based.node_ele", node_ele(node_text(TET_V), ele_text([(0, 1, 2, 3)])))
put("node_ele", "tet_1based_attributes_region.node_ele",
    node_ele(node_text(TET_V, 1, 2, 1), ele_text([(0, 1, 2, 3)], 1, region=7)))
put("node_ele", "two_tets_one_flipped.node_ele",
    node_ele(node_text(TET_V + [(0, 0, -1)]), ele_text([(0, 1, 2, 3), (0, 1, 2, 4)])))
put("node_ele", "quadratic_tet.node_ele",
    node_ele(node_text(quad, 1), ele_text([tuple(range(10))], 1, per=10)))
put("node_ele", "comments_blank_lines_crlf.node_ele",
    node_ele("# points\r\n\r\n" + node_text(TET_V).replace("\n", "  # c\r\n"),
             "\r\n# tets\r\n" + ele_text([(0, 1, 2, 3)]).replace("\n", "\r\n")))
put("node_ele", "short_headers.node_ele",
    node_ele("4\n" + "".join("%d %g %g %g\n" % ((i,) + p) for i, p in enumerate(TET_V)),
             "1\n0 0 1 2 3\n"))
# Nearly valid: each refused for one reason.
put("node_ele", "no_ele.node_ele", node_text(TET_V).encode())
put("node_ele", "flat_tet.node_ele",
    node_ele(node_text([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)]), ele_text([(0, 1, 2, 3)])))
put("node_ele", "node_out_of_range.node_ele", node_ele(node_text(TET_V), "1 4 0\n0 0 1 2 4\n"))
put("node_ele", "extra_point_line.node_ele",
    node_ele(node_text(TET_V) + "4 1 1 1\n", ele_text([(0, 1, 2, 3)])))
put("node_ele", "huge_coordinates.node_ele",
    node_ele(node_text([(0, 0, 0), (1e200, 0, 0), (0, 1e200, 0), (0, 0, 1e200)]),
             ele_text([(0, 1, 2, 3)])))
put("node_ele", "subnormal_coordinate.node_ele",
    node_ele(node_text(TET_V).replace("0.0 0.0 0.0\n", "0.0 0.0 1e-310\n", 1),
             ele_text([(0, 1, 2, 3)])))

# ------------------------------------------------ substructure cache: edits of the cached files
# Byte 0: which of the five files (three blocks, two planes; bit 7: cut the body short), then
# (u32 offset, u8 xor) edits, then, when cut, a u32 length (substructure_cache_fuzz.cc).
def edits(*pairs):
    return b"".join(struct.pack("<IB", offset, mask) for offset, mask in pairs)


for f in range(5):
    put("substructure_cache", "file%d_unchanged.bin" % f, bytes([f]))
    put("substructure_cache", "file%d_header_byte.bin" % f, bytes([f]) + edits((4, 0x01)))
    put("substructure_cache", "file%d_middle_bytes.bin" % f,
        bytes([f]) + edits((0x40000, 0x80), (0x7FFFF, 0x10), (123457, 0xFF)))
    put("substructure_cache", "file%d_cut.bin" % f, bytes([f | 0x80]) + struct.pack("<I", 1000))
put("substructure_cache", "file0_sizes_and_cut.bin",
    bytes([0x80]) + edits((12, 0x7F), (40, 0x01)) + struct.pack("<I", 99))
