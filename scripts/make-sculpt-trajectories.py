#!/usr/bin/env python3
# Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
"""Writes assets/trajectories/sculpt_grab.csv, sculpt_twist.csv and sculpt_bend.csv: one sculpt
stroke each on the clay of assets/scenes/clay_sculpt.json, for
`spidarcad run assets/scenes/clay_sculpt.json --world-origin 0,-0.038,0.0739 --sculpt-tool TOOL`:
that X_WD (scale 1) puts the clay's top, the surface vertex near (0, -0.038, 0.0739) m (W) with
its outward normal about +z, at the device origin, where the SPIDAR-G displays forces and
moments best (with the identity X_WD the top is 74 mm up and the tensions saturate for up to a
third of the run). Positions are in D, metres.

Each run: the grip waits 15 mm above the clay's top at rest orientation and grasp pi/2 while the
loop's start ramp passes (0.6 s), comes down onto that point (0.6-1.0 s), closes the grasp to
0.5 rad (1.0-1.3 s; the stroke begins when the measured grasp falls below 70 deg, and the grab
strength is 1 from 45 deg down), then moves (1.4-2.4 s):
  grab   the grip pulls 30 mm up, out of the clay (the hand, 300 N/m, against the stroke's
         300 N/m, gets about half way)
  twist  the grip turns 0.8 rad about its z axis (vertical)
  bend   the grip turns 0.5 rad about its y axis (horizontal)
and holds (2.4-3.0 s). The grasp stays closed to the end: the run ends the stroke at its last
tick with the full deformation (opening the grasp first would let the clay spring back, as the
grab strength falls from 1 at 45 deg to 0.22 at the 80 deg where the stroke ends).
Smooth (cosine) blends between key poses, 50 samples/s.

It also writes sculpt_pinch_hard.csv and sculpt_pinch_light.csv, the same pinch with a hard and a
light squeeze (the clay width, app/src/scene/clay_width.h): the grip at rest orientation (its
bisector b = (1, 1, 0)/sqrt 2 horizontal, the poles in the horizontal plane, where the SPIDAR-G
renders forces without saturating) waits 15 mm out along -b from PINCH_AT, beside the clay's top
lobe, comes in to it (0.6-1.0 s) and closes the grasp (1.0-1.4 s) towards PINCH_HARD or
PINCH_LIGHT. The fingertips meet the clay near 80 deg, above the 70 deg angle trigger, so the
squeeze begins the stroke and the clay stops the fingers; the hand's grasp spring (0.5 N m/rad)
pushes them on by (measured angle - commanded angle), and that sets the squeeze. The grip then
pulls 20 mm out along -b (1.6-2.4 s), holds (2.4-2.8 s), opens the grasp to pi/2 (2.8-3.2 s:
the fingers let go of the clay, which stays as the firmest squeeze left it) and backs off 15 mm
(3.2-3.6 s) to the end (3.8 s). PINCH_AT was found by moving the grip in along -b at 80 deg until
the fingertips met the clay.

Usage: scripts/make-sculpt-trajectories.py [OUT_DIR, default assets/trajectories]
"""
import math
import os
import sys

RATE = 50.0
HALF_PI = math.pi / 2
GRASP_CLOSED = 0.5  # rad
TOP = (0.0, 0.0, 0.0)  # m (D): the clay's top with --world-origin 0,-0.038,0.0739
ABOVE = (TOP[0], TOP[1], TOP[2] + 0.015)


PINCH_AT = (-0.0404, -0.0474, -0.0199)  # m (D): fingertips meet the clay near 80 deg here
PINCH_OUT = (-1 / math.sqrt(2), -1 / math.sqrt(2), 0.0)  # -b at rest orientation
PINCH_HARD = 0.9  # rad, the grasp the hand is asked for
PINCH_LIGHT = 1.25  # rad


def axis_angle(axis, angle):
    s = math.sin(angle / 2)
    return (math.cos(angle / 2), axis[0] * s, axis[1] * s, axis[2] * s)


def keys(motion):
    """Key poses (t, position, quaternion, grasp) of one stroke."""
    rest = (1.0, 0.0, 0.0, 0.0)
    start = [(0.0, ABOVE, rest, HALF_PI), (0.6, ABOVE, rest, HALF_PI), (1.0, TOP, rest, HALF_PI),
             (1.3, TOP, rest, GRASP_CLOSED), (1.4, TOP, rest, GRASP_CLOSED)]
    if motion == "grab":
        end = ((TOP[0], TOP[1], TOP[2] + 0.03), rest)
    elif motion == "twist":
        end = (TOP, axis_angle((0.0, 0.0, 1.0), 0.8))
    else:
        end = (TOP, axis_angle((0.0, 1.0, 0.0), 0.5))
    return start + [(2.4, end[0], end[1], GRASP_CLOSED), (3.0, end[0], end[1], GRASP_CLOSED)]


def pinch_keys(grasp):
    """Key poses of a pinch with the grasp asked to close to `grasp`."""
    def out(dist):
        return tuple(a + dist * u for a, u in zip(PINCH_AT, PINCH_OUT))
    q = (1.0, 0.0, 0.0, 0.0)
    return [(0.0, out(0.015), q, HALF_PI), (0.6, out(0.015), q, HALF_PI),
            (1.0, PINCH_AT, q, HALF_PI), (1.4, PINCH_AT, q, grasp), (1.6, PINCH_AT, q, grasp),
            (2.4, out(0.02), q, grasp), (2.8, out(0.02), q, grasp), (3.2, out(0.02), q, HALF_PI),
            (3.6, out(0.035), q, HALF_PI), (3.8, out(0.035), q, HALF_PI)]


def slerp(a, b, u):
    d = sum(x * y for x, y in zip(a, b))
    if d < 0:
        b, d = tuple(-x for x in b), -d
    if d > 0.9999999:
        q = tuple(x + u * (y - x) for x, y in zip(a, b))
    else:
        th = math.acos(d)
        q = tuple((math.sin((1 - u) * th) * x + math.sin(u * th) * y) / math.sin(th)
                  for x, y in zip(a, b))
    n = math.sqrt(sum(x * x for x in q))
    return tuple(x / n for x in q)


def write(path, motion, k=None):
    k = k if k is not None else keys(motion)
    lines = ["# sculpt stroke '%s' on the top of assets/scenes/clay_sculpt.json's clay (run it with"
             " --world-origin 0,-0.038,0.0739); written by scripts/make-sculpt-trajectories.py"
             % motion,
             "# t,x,y,z,qw,qx,qy,qz,grasp (s, m in the device frame D, unit quaternion R_DT, rad)"]
    n = int(round(k[-1][0] * RATE))
    for i in range(n + 1):
        t = i / RATE
        j = 0
        while j + 2 < len(k) and k[j + 1][0] <= t:
            j += 1
        t0, p0, q0, g0 = k[j]
        t1, p1, q1, g1 = k[j + 1]
        u = min(1.0, max(0.0, (t - t0) / (t1 - t0)))
        u = 0.5 - 0.5 * math.cos(math.pi * u)
        p = tuple(a + u * (b - a) for a, b in zip(p0, p1))
        q = slerp(q0, q1, u)
        g = g0 + u * (g1 - g0)
        lines.append(",".join(repr(round(v, 12)) for v in (t,) + p + q + (g,)))
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "assets", "trajectories")
    for motion in ("grab", "twist", "bend"):
        write(os.path.join(out, "sculpt_%s.csv" % motion), motion)
    for name, grasp in (("pinch_hard", PINCH_HARD), ("pinch_light", PINCH_LIGHT)):
        write(os.path.join(out, "sculpt_%s.csv" % name), name, pinch_keys(grasp))


if __name__ == "__main__":
    main()
