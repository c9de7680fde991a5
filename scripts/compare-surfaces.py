#!/usr/bin/env python3
# Compares two surface meshes (.obj, as `spidarcad mesh ... --out x.obj` writes them) triangle by
# triangle: for each x range between the given edges, how many triangles (corners all in the
# range, matched by their vertex positions rounded to 1e-12 m) are in one mesh and not the other,
# and the x extent of all triangles that differ. Used to check that the surface mesher is local
# (docs/design/2026-12-02-edit-to-feel.md).
# Usage: scripts/compare-surfaces.py a.obj b.obj -1,0.06,0.12,0.18,0.24,0.3,1
import sys


def read_obj(path):
    vertices, faces = [], []
    with open(path) as f:
        for line in f:
            t = line.split()
            if not t:
                continue
            if t[0] == "v":
                vertices.append(tuple(float(x) for x in t[1:4]))
            elif t[0] == "f":
                faces.append(tuple(int(x.split("/")[0]) - 1 for x in t[1:4]))
    return vertices, faces


def triangles(mesh, lo, hi):
    vertices, faces = mesh
    out = set()
    for face in faces:
        corners = [vertices[i] for i in face]
        if all(lo <= p[0] < hi for p in corners):
            out.add(tuple(sorted(tuple(round(x, 12) for x in p) for p in corners)))
    return out


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__ or "usage: compare-surfaces.py a.obj b.obj EDGES")
    a, b = read_obj(sys.argv[1]), read_obj(sys.argv[2])
    edges = [float(x) for x in sys.argv[3].split(",")]
    for lo, hi in zip(edges[:-1], edges[1:]):
        ta, tb = triangles(a, lo, hi), triangles(b, lo, hi)
        print(f"x in [{lo:.3f}, {hi:.3f}): {len(ta)} / {len(tb)} triangles, "
              f"{len(ta - tb)} only in the first, {len(tb - ta)} only in the second")
    ta, tb = triangles(a, -1e9, 1e9), triangles(b, -1e9, 1e9)
    differ = (ta - tb) | (tb - ta)
    if differ:
        xs = [p[0] for t in differ for p in t]
        print(f"{len(differ)} triangles differ, all within x = {min(xs):.4f} .. {max(xs):.4f} m")


if __name__ == "__main__":
    main()
