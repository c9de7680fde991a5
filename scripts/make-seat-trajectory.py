#!/usr/bin/env python3
# Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
"""Writes assets/trajectories/seat_right_leg.csv: the grip picks up the right leg of
assets/scenes/assembly.json and seats it under the torso, starting from the window's default grip
(origin, rest orientation, grasp 90 deg).

The grip keeps its rest orientation throughout (the poles horizontal): the leg stands upright, so
its 16 mm square section lies in the poles' plane, and the SPIDAR-G measures and drives the grip
best near rest (a grip turned by 90-120 deg, as the right arm's section would need, costs force
closure: the tension solve saturates and the grasp torque pushes the grip sideways). The grip
centre sits 24 mm from the leg's axis along -b (b = (1,1,0)/sqrt2, the poles' bisector), as in
tests/app/assembly_scene_test.cc's scripted run for the arm; closing the grasp picks the leg up;
it is lifted over the head, lowered in front of the torso, moved under the right hip hole and
pushed up into it (0.5 mm past the seated pose: the torso stops it), and let go: it snaps to its
seat. X_WD is the identity (what `spidarcad run` and the window use for assembly scenes), so the
positions are device coordinates. Smooth (cosine) blends between key poses, 50 samples/s.

With --whole-robot it writes assets/trajectories/whole_robot.csv instead: one trajectory that
picks up, carries and seats all five parts in turn (head, right leg, left leg, right arm, left
arm; see whole_robot_keys below), each key pose a grip pose (centre and orientation) and grasp.

Usage: scripts/make-seat-trajectory.py [OUT.csv]
       scripts/make-seat-trajectory.py --whole-robot [OUT.csv]
"""
import math
import sys

import trajectory_keys

RATE = 50.0
HALF_PI = math.pi / 2

Q_REST = (1.0, 0.0, 0.0, 0.0)
GRASP_CLOSED = 0.45  # rad: the poles meet the leg's 16 mm section at about 0.87 rad; the hand squeezes on

# The right leg (solid "leg": a 16 mm square bar 50 mm long below its frame origin, the peg
# above it once the part is turned 180 deg about x) stands upright at (0.02, 0.1, 0.0505); its
# seat is under the torso's right hip hole, (0.012, 0, 0.0545) = body (0, 0, 0.085) + seat
# (0.012, 0, -0.0305). The grip holds it at rest orientation, the poles (horizontal) across the
# bar 8.5 mm below its top, the grip centre 24 mm from the bar's axis along -b, b = (1,1,0)/sqrt2.
OFFSET = (-0.024 / math.sqrt(2.0), -0.024 / math.sqrt(2.0), -0.0085)
START = (0.02, 0.1, 0.0505)
SEAT = (0.012, 0.0, 0.0545)


def add(a, b):
    return tuple(p + q for p, q in zip(a, b))


def grip(leg):
    return add(leg, OFFSET)


ORIGIN = (0.0, 0.0, 0.0)
UP = grip(add(START, (0.0, 0.0, 0.025)))  # grip above its grasp pose

# (duration of the move to this key, grip centre, grasp, comment)
KEYS = [
    (0.0, ORIGIN, HALF_PI, "start: the window's default grip, held through the force ramp"),
    (0.6, ORIGIN, HALF_PI, None),
    (0.8, (0.0, 0.0, UP[2]), HALF_PI, "up, clear of the parts"),
    (1.2, UP, HALF_PI, "over the right leg, the poles above the head"),
    (1.0, grip(START), HALF_PI, "down: the leg's section between the poles"),
    (0.4, grip(START), HALF_PI, None),
    (1.5, grip(START), GRASP_CLOSED, "close the grasp: the poles squeeze the leg, it is picked up"),
    (0.5, grip(START), GRASP_CLOSED, None),
    (1.2, grip(add(START, (0.0, 0.0, 0.04))), GRASP_CLOSED, "lift the leg clear of the head"),
    (2.0, grip(add(START, (-0.008, -0.07, 0.04))), GRASP_CLOSED, "over the head, toward the torso"),
    (1.2, grip(add(START, (-0.008, -0.07, -0.006))), GRASP_CLOSED, "down in front of the torso, the peg below its bottom"),
    (1.5, grip(add(SEAT, (0.0, 0.0, -0.010))), GRASP_CLOSED, "under the right hip hole"),
    (0.5, grip(add(SEAT, (0.0, 0.0, -0.010))), GRASP_CLOSED, None),
    (1.5, grip(add(SEAT, (0.0, 0.0, 0.0005))), GRASP_CLOSED, "up: the peg into the hole, 0.5 mm past the seat"),
    (0.5, grip(add(SEAT, (0.0, 0.0, 0.0005))), GRASP_CLOSED, None),
    (1.0, grip(add(SEAT, (0.0, 0.0, 0.0005))), HALF_PI, "open: the leg is released and snaps to its seat"),
    (0.5, grip(add(SEAT, (0.0, 0.0, 0.0005))), HALF_PI, None),
    (1.0, grip(add(SEAT, (-0.03, -0.03, -0.01))), HALF_PI, "back away along -b, the poles leave the leg"),
    (1.0, grip(add(SEAT, (-0.03, -0.03, -0.03))), HALF_PI, "and down"),
    (0.5, grip(add(SEAT, (-0.03, -0.03, -0.03))), HALF_PI, None),
]


def slerp(a, b, s):
    dot = sum(p * q for p, q in zip(a, b))
    if dot < 0:
        b, dot = tuple(-q for q in b), -dot
    if dot > 0.9995:
        r = tuple(p + s * (q - p) for p, q in zip(a, b))
    else:
        th = math.acos(dot)
        r = tuple((math.sin((1 - s) * th) * p + math.sin(s * th) * q) / math.sin(th) for p, q in zip(a, b))
    n = math.sqrt(sum(c * c for c in r))
    return tuple(c / n for c in r)


# The whole robot. Each part is held by a grip offset from a point of the part (its "hold"
# point, in W while the part is at a given pose: the part only translates here, so the offset
# stays); the grip orientation is the rest one except for the left arm, which lies along x: for
# it the grip is pitched 90 deg about y (T's xy plane becomes W's yz plane, the arm's 12 mm square
# section between the poles; the poles' bisector b_W = (0, 1, -1)/sqrt2), as in
# tests/app/assembly_scene_test.cc's ScriptedRunSeatsTheRightArm. The body's frame is at
# (0, 0, 0.085); seats are body + X_OS (assets/scenes/assembly.json).
Q_PITCH = (math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0)  # 90 deg about y
B_REST = (1.0 / math.sqrt(2.0), 1.0 / math.sqrt(2.0), 0.0)
B_PITCH = (0.0, 1.0 / math.sqrt(2.0), -1.0 / math.sqrt(2.0))


def scale(a, k):
    return tuple(k * p for p in a)


def part_keys(start, seat, hold, b, l_hold, q, closed, approach, insert, clear, via=()):
    """Key poses that pick a part up at `start` (its frame origin), carry it through `approach`
    (part origins, relative to the seat, the last one in line with the seat along the insertion
    direction), push it `insert` past the seat (a vector), open and back the grip off along
    `clear`. `hold` is the hold point relative to the part origin, `b` the bisector in W, l_hold
    its distance from the grip centre, q the grip orientation, closed the grasp it closes to."""
    off = add(hold, scale(b, -l_hold))

    def g(origin):
        return add(origin, off)

    keys = [(1.5, v, q, HALF_PI, "around the parts" if i == 0 else None) for i, v in enumerate(via)]
    keys.append((1.5, add(g(start), (0.0, 0.0, 0.03)), q, HALF_PI, "over the %s" % PART))
    keys.append((1.0, g(start), q, HALF_PI, "down: its section between the poles"))
    keys.append((0.4, g(start), q, HALF_PI, None))
    keys.append((1.5, g(start), q, closed, "close: the poles squeeze it, it is picked up"))
    keys.append((0.5, g(start), q, closed, None))
    keys.append((1.0, g(add(start, (0.0, 0.0, 0.03))), q, closed, "lift it"))
    for rel, duration, comment in approach:
        keys.append((duration, g(add(seat, rel)), q, closed, comment))
    keys.append((0.5, keys[-1][1], q, closed, None))
    keys.append((1.5, g(add(seat, insert)), q, closed, "the peg into its hole, just past the seat"))
    keys.append((0.5, g(add(seat, insert)), q, closed, None))
    keys.append((1.0, g(add(seat, insert)), q, HALF_PI, "open: released, it snaps to its seat"))
    keys.append((0.5, g(add(seat, insert)), q, HALF_PI, None))
    keys.append((1.0, add(g(add(seat, insert)), clear), q, HALF_PI, "back away"))
    return keys


PART = ""
ARM_CLOSED = 0.65
LEFT_ARM_CLOSED = 0.45
ARM_L = 0.02
ARM_PUSH = 0.0005


def whole_robot_keys():
    global PART
    body = (0.0, 0.0, 0.085)
    keys = [
        (0.0, ORIGIN, Q_REST, HALF_PI, "start: the window's default grip, held through the force ramp"),
        (0.6, ORIGIN, Q_REST, HALF_PI, None),
        (0.8, (0.0, 0.0, 0.03), Q_REST, HALF_PI, "up, below the torso (its bottom at z = 0.055 m)"),
    ]
    # Head: a 24 mm cube on a peg, upright; held at mid-height, 32 mm from its axis along -b.
    PART = "head"
    keys += part_keys(start=(0.0, 0.07, 0.0085), seat=add(body, (0.0, 0.0, 0.0305)),
                      hold=(0.0, 0.0, 0.012), b=B_REST, l_hold=0.032, q=Q_REST, closed=0.55,
                      approach=[((0.0, 0.07, 0.03), 1.5, "over the torso's side"),
                                ((0.0, 0.0, 0.02), 2.0, "above the neck hole")],
                      insert=(0.0, 0.0, -0.0005), clear=(-0.03, -0.03, 0.01))
    # Legs: as seat_right_leg.csv (16 mm bar, 24 mm from its axis, 8.5 mm below its top).
    for name, x, xs, via in (("right leg", 0.02, 0.012, [(-0.0526, 0.083, 0.1375)]),
                             ("left leg", -0.02, -0.012, [])):
        PART = name
        keys += part_keys(via=via, start=(x, 0.1, 0.0505), seat=add(body, (xs, 0.0, -0.0305)),
                          hold=(0.0, 0.0, -0.0085), b=B_REST, l_hold=0.024, q=Q_REST,
                          closed=GRASP_CLOSED,
                          approach=[((x - xs, 0.03, 0.02), 2.0, "toward the torso, in front of it"),
                                    ((0.0, 0.03, -0.01), 1.2, "down, the peg below the torso"),
                                    ((0.0, 0.0, -0.01), 1.5, "under its hip hole")],
                          insert=(0.0, 0.0, 0.0005), clear=(-0.03, -0.03, -0.02))
    # Arms: lying along +x (right) or -x (left), the peg toward the torso (-x for the right arm).
    # The right arm with the grip at rest: the poles (horizontal) close on the corner of its -y
    # face and its peg end (the peg steadies the pole on the end), the grip centre ARM_L from
    # that corner along -b. The left arm's end facing -x has no peg (a pole on it slips past the
    # corner), so it is held across its bulk with the grip pitched 90 deg about y (the poles'
    # plane vertical, around its 12 mm square section), 20 mm from the middle of the bulk (17.5 mm
    # along P's z), as in tests/app/assembly_scene_test.cc's ScriptedRunSeatsTheRightArm.
    PART = "right arm"
    keys += part_keys(via=[(0.03, -0.047, 0.03)], start=(0.04, 0.06, 0.0065),
                      seat=add(body, (0.0255, 0.0, 0.018)), hold=(0.0, -0.006, 0.0), b=B_REST,
                      l_hold=ARM_L, q=Q_REST, closed=ARM_CLOSED,
                      approach=[((0.03, 0.06, 0.0), 2.0, "beside the torso, level with the shoulder"),
                                ((0.03, 0.0, 0.0), 1.5, "level with the shoulder hole"),
                                ((0.01, 0.0, 0.0), 1.0, "in line with it")],
                      insert=(-ARM_PUSH, 0.0, 0.0), clear=(-0.02, -0.02, 0.0))
    keys.append((1.0, add(keys[-1][1], (0.0, 0.0, 0.05)), Q_REST, HALF_PI, "up"))
    keys.append((1.5, keys[-1][1], Q_PITCH, HALF_PI, "turn the grip: the poles' plane vertical"))
    PART = "left arm"
    keys += part_keys(via=[(-0.0575, -0.044, 0.16)], start=(-0.04, 0.06, 0.0065),
                      seat=add(body, (-0.0255, 0.0, 0.018)), hold=(-0.0175, 0.0, 0.0), b=B_PITCH,
                      l_hold=0.02, q=Q_PITCH, closed=LEFT_ARM_CLOSED,
                      approach=[((-0.03, 0.06, 0.0), 2.0, "beside the torso, level with the shoulder"),
                                ((-0.01, 0.0, 0.0), 1.5, "in line with the shoulder hole")],
                      insert=(ARM_PUSH, 0.0, 0.0), clear=(0.0, -0.03, 0.03))
    keys.append((1.5, keys[-1][1], Q_REST, HALF_PI, "the grip back to rest"))
    keys.append((0.5, keys[-1][1], Q_REST, HALF_PI, None))
    return keys


def write_whole_robot(out):
    intro = [
        "# whole_robot: pick up, carry and seat all five parts of assets/scenes/assembly.json in turn",
        "# (head, right leg, left leg, right arm, left arm) from the window's default grip;",
        "# X_WD identity (as `spidarcad run`). generated by scripts/make-seat-trajectory.py --whole-robot;",
        "# key poses:",
    ]
    trajectory_keys.write(out, intro, whole_robot_keys(), RATE, slerp=slerp)


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--whole-robot":
        write_whole_robot(sys.argv[2] if len(sys.argv) > 2 else "assets/trajectories/whole_robot.csv")
        return
    out = sys.argv[1] if len(sys.argv) > 1 else "assets/trajectories/seat_right_leg.csv"
    intro = [
        "# seat_right_leg: pick up the right leg of assets/scenes/assembly.json and seat it under the torso",
        "# from the window's default grip (origin, rest, grasp 90 deg); X_WD identity (as `spidarcad run`).",
        "# generated by scripts/make-seat-trajectory.py; key poses:",
    ]
    keys = [(d, p, Q_REST, g, c) for d, p, g, c in KEYS]
    trajectory_keys.write(out, intro, keys, RATE)

if __name__ == "__main__":
    main()
