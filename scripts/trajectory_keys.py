# Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
"""Key-pose trajectories for the make-*-trajectory.py scripts: cosine blends between key poses
of the grip, sampled at a fixed rate, written as a trajectory CSV (docs/cli.md) with a comment
header that lists the key poses.

A key is (duration of the move to it in s, grip centre (x, y, z) in m in the device frame D,
orientation R_DT as a unit quaternion (w, x, y, z), grasp, comment or None). The grasp is blended
in whatever unit the keys use and written through `grasp_out` (radians in the file).
"""
import math

COLUMNS = "# t,x,y,z,qw,qx,qy,qz,grasp (s, m in the device frame D, unit quaternion R_DT, rad)"


def blend(keys, rate, slerp=None):
    """Samples (t, position, quaternion, grasp) from the first key's pose at t = 0 through every
    key, each move a cosine blend of round(duration * rate) steps. Without `slerp` a sample takes
    its target key's quaternion (keys of one orientation); with it, slerp(q0, q1, s)."""
    samples = [(0.0, keys[0][1], keys[0][2], keys[0][3])]
    t = 0.0
    prev = keys[0]
    for key in keys[1:]:
        duration = key[0]
        n = max(1, int(round(duration * rate)))
        for k in range(1, n + 1):
            s = 0.5 - 0.5 * math.cos(math.pi * k / n)  # cosine blend
            p = tuple(a + s * (b - a) for a, b in zip(prev[1], key[1]))
            q = key[2] if slerp is None else slerp(prev[2], key[2], s)
            g = prev[3] + s * (key[3] - prev[3])
            samples.append((t + duration * k / n, p, q, g))
        t += duration
        prev = key
    return samples


def write(out, intro, keys, rate, time_format="%.1f", slerp=None, grasp_out=lambda g: g):
    """Writes `intro` (comment lines), one comment per key that has one (at the time the move to
    it ends), the column line and the blended samples to `out`."""
    lines = list(intro)
    t = 0.0
    for key in keys:
        t += key[0]
        if key[4]:
            lines.append("#   t=" + time_format % t + " s: " + key[4])
    lines.append(COLUMNS)
    for ts, p, q, g in blend(keys, rate, slerp):
        vals = [round(ts, 4)] + list(p) + list(q) + [grasp_out(g)]
        lines.append(",".join("%.10g" % v for v in vals))
    with open(out, "w") as f:
        f.write("\n".join(lines) + "\n")
