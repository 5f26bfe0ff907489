#!/usr/bin/env python3
"""iges_write.py: small IGES 5.3 files for the tests - fixed 80 columns, Global section with a unit
flag, Directory pairs, free-format parameters split into 64-column lines with their DE pointer.

  write(path, entities, unit=2)   entities: list of dicts {type, params, form=0, status=0,
                                  transform=None, color=0}; pointers (in params, transform, and a
                                  colour ('D', k)) are entity indices and become directory lines 2k + 1.
Run as a script, it writes the hand-made parts the IGES tests use (see parts())."""
import math
import sys


def _fmt(v):
    if isinstance(v, tuple) and v[0] == "D":
        return str(2 * v[1] + 1)
    if isinstance(v, str):
        return "%dH%s" % (len(v), v)
    if isinstance(v, int):
        return str(v)
    return repr(float(v)).replace("e", "D")


def _ptr(v):
    """An entity index (or ('D', k)) as its directory line; 0 for None."""
    if v is None:
        return 0
    return 2 * (v[1] if isinstance(v, tuple) else v) + 1


def write(path, entities, unit=2, unit_name="MM"):
    lines = ["%-72sS%7d" % ("surfd test part", 1)]
    glob = ",".join(["1H,", "1H;", "4Htest", "8Htest.igs", "5Hsurfd", "5Hsurfd", "32", "38", "6", "308", "15",
                     "4Htest", "1.0", str(unit), "%dH%s" % (len(unit_name), unit_name), "1", "0.01",
                     "15H20261202.000000", "0.001", "1000.0", "4Htest", "4Htest", "11", "0",
                     "15H20261202.000000"]) + ";"
    for k in range(0, len(glob), 72):
        lines.append("%-72sG%7d" % (glob[k:k + 72], k // 72 + 1))
    d_lines, p_lines = [], []
    for i, e in enumerate(entities):
        fields = [str(e["type"])] + [_fmt(v) for v in e["params"]]
        first = len(p_lines) + 1
        chunks, cur = [], ""  # lines break after a delimiter, never inside a parameter
        for k, f in enumerate(fields):
            f += ";" if k == len(fields) - 1 else ","
            if len(cur) + len(f) > 64:
                chunks.append(cur)
                cur = ""
            cur += f
        chunks.append(cur)
        for c in chunks:
            p_lines.append("%-64s %7dP%7d" % (c, 2 * i + 1, len(p_lines) + 1))
        color = e.get("color")
        color = -_ptr(color) if isinstance(color, tuple) else (color or 0)
        d_lines.append("%8d%8d%8d%8d%8d%8d%8d%8d%8sD%7d" % (e["type"], first, 0, 0, 0, 0, _ptr(e.get("transform")), 0,
                                                              "%08d" % e.get("status", 0), 2 * i + 1))
        d_lines.append("%8d%8d%8d%8d%8d%8s%8s%8s%8dD%7d" % (e["type"], 0, color, len(chunks), e.get("form", 0), "", "",
                                                              "", 0, 2 * i + 2))
    lines += d_lines + p_lines
    lines.append("%-72sT%7d" % ("S%7dG%7dD%7dP%7d" % (1, (len(glob) + 71) // 72, len(d_lines), len(p_lines)), 1))
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def plane(size, status=10000, transform=None):
    """A bilinear 128 over [0, 1]^2: the square [0, size]^2 at z = 0."""
    pts = [0, 0, 0, size, 0, 0, 0, size, 0, size, size, 0]
    return {"type": 128, "status": status, "transform": transform,
            "params": [1, 1, 1, 1, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 0, 1, 1, 1, 1, 1, 1] + pts + [0, 1, 0, 1]}


def arc(cx, cy, r, status=10500):
    """A full circle (100) in the plane z = 0 of its space."""
    return {"type": 100, "status": status, "params": [0, cx, cy, cx + r, cy, cx + r, cy]}


def line(a, b, status=10500):
    return {"type": 110, "status": status, "params": list(a) + list(b)}


def circle_126(cx, cy, r, status=10500):
    """A rational quadratic B-spline circle (126, 9 points) in the plane z = 0."""
    w = math.sqrt(0.5)
    knots = [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]
    pts = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1), (1, 0)]
    ws = [1, w, 1, w, 1, w, 1, w, 1]
    xyz = []
    for x, y in pts:
        xyz += [cx + r * x, cy + r * y, 0]
    return {"type": 126, "status": status,
            "params": [8, 2, 1, 1, 0, 0] + knots + ws + xyz + [0, 1, 0, 0, 1]}


def plate_hole(unit=2):
    """A 100 mm plate (144, natural boundary) with a hole: a 100 arc of radius 0.25 in (u, v)."""
    return [plane(100), arc(0.5, 0.5, 0.25),
            {"type": 142, "status": 10000, "params": [0, ("D", 0), ("D", 1), 0, 2]},
            {"type": 144, "params": [("D", 0), 0, 1, 0, ("D", 2)]}]


def plate_square():
    """Outer loop a 102 of four 110 lines (the square [0.1, 0.9]^2 in (u, v)), a hole a 126 circle of
    radius 0.2; the plate moved by a 124 (10, 20, 30), coloured red by a 314."""
    sq = [(0.1, 0.1, 0), (0.9, 0.1, 0), (0.9, 0.9, 0), (0.1, 0.9, 0)]
    ents = [{"type": 124, "status": 10000, "params": [1, 0, 0, 10, 0, 1, 0, 20, 0, 0, 1, 30]},
            plane(100, transform=0)]                                                         # 0, 1
    ents += [line(sq[k], sq[(k + 1) % 4]) for k in range(4)]                                   # 2..5
    ents.append({"type": 102, "status": 10500, "params": [4, ("D", 2), ("D", 3), ("D", 4), ("D", 5)]})  # 6
    ents.append({"type": 142, "status": 10000, "params": [0, ("D", 1), ("D", 6), 0, 2]})     # 7
    ents.append(circle_126(0.5, 0.5, 0.2))                                                  # 8
    ents.append({"type": 142, "status": 10000, "params": [0, ("D", 1), ("D", 8), 0, 2]})     # 9
    ents.append({"type": 314, "status": 200, "params": [90.0, 10.0, 10.0, "red"]})          # 10
    ents.append({"type": 144, "color": ("D", 10), "params": [("D", 1), 1, 1, ("D", 7), ("D", 9)]})  # 11
    return ents


def plate_model():
    """A 143 bounded by a 141 whose one curve is in model space only (a 126 circle of radius 30 about
    (50, 50, 0), K = 0): the loop is its projection onto the plate."""
    c = circle_126(50, 50, 30, status=10000)
    return [plane(100), c, {"type": 141, "status": 10000, "params": [1, 1, ("D", 0), 1, ("D", 1), 1, 0]},
            {"type": 143, "params": [1, ("D", 0), 1, ("D", 2)]}]


def plate_group():
    """plate_hole as CAD systems write a part (Open CASCADE's samples): its 144 logically dependent
    (subordinate switch 02), a member of a 402 group (form 7: unordered, no back pointers) named
    "Plate7" by a 406 (form 15); drawn as an independent one is, under its group's name."""
    ents = plate_hole()
    ents[3]["status"] = 20000
    ents.append({"type": 402, "form": 7, "params": [1, ("D", 3), 0, 1, ("D", 5)]})
    ents.append({"type": 406, "form": 15, "status": 10000, "params": [1, "Plate7"]})
    return ents


def parts(out):
    """Writes the hand-made parts into out; returns {name: area in mm^2}."""
    write(out + "/plate_hole.igs", plate_hole())
    write(out + "/plate_inch.igs", plate_hole(), unit=1, unit_name="IN")
    write(out + "/plate_square.igs", plate_square())
    write(out + "/plate_model.igs", plate_model())
    write(out + "/plate_group.igs", plate_group())
    hole = 10000 - math.pi * 25 ** 2
    return {"plate_hole": hole, "plate_inch": hole * 25.4 ** 2, "plate_square": 80 ** 2 - math.pi * 20 ** 2,
            "plate_model": math.pi * 30 ** 2, "plate_group": hole}


if __name__ == "__main__":
    for name, area in parts(sys.argv[1]).items():
        print(name, "%.6f" % area)
