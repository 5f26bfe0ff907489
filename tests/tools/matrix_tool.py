#!/usr/bin/python3
"""Matrix models (seed 003) for tests/api/matrix.sh and the bench, standard library only: a shape's
voxels (centres inside) and their six relief matrices in Table 1's layout (METHODS.md §5),
computed here independently of surfd.

  matrix_tool.py ball N R OUT.json          a ball of radius R voxels in N^3 voxels
  matrix_tool.py box N X0 X1 Y0 Y1 Z0 Z1 OUT.json
  matrix_tool.py steps N OUT.json          a stepped pyramid (every axis line meets it once)
  matrix_tool.py mask N SHAPE... OUT.raw    the shape's voxels as uint8 samples (255 inside), x fastest
  matrix_tool.py silhouette MATRICES.json K VIEW.png
                                            the pixels where view K's image (an orthographic render
                                            from matrix K's face, a pixel a voxel line, magenta
                                            background) and matrix K disagree on whether the line
                                            meets the body, printed (0: the same)
Every file's voxel size is 1 mm, its box [0, N]^3 mm."""
import json
import sys

import png_read


def inside(shape, n, x, y, z):
    c = (x + 0.5, y + 0.5, z + 0.5)
    if shape[0] == "ball":
        r = float(shape[1])
        return sum((c[i] - n / 2.0) ** 2 for i in range(3)) < r * r
    if shape[0] == "box":
        b = [int(v) for v in shape[1:7]]
        return b[0] <= x < b[1] and b[2] <= y < b[3] and b[4] <= z < b[5]
    if shape[0] == "steps":  # layers shrinking upwards, every layer a centred square
        h = n // 2 - 1 - z // 2
        return z < n - 2 and h > 0 and abs(x + 0.5 - n / 2.0) < h and abs(y + 0.5 - n / 2.0) < h
    raise SystemExit("unknown shape")


def matrices(vox, n):
    N = M = K = n
    def first(cells):
        for d, (x, y, z) in enumerate(cells):
            if vox[x][y][z]:
                return d
        return len(cells)
    mm = {
        "M0": [[first([(N - 1 - d, j, K - 1 - i) for d in range(N)]) for j in range(M)] for i in range(K)],
        "M1": [[first([(N - 1 - j, M - 1 - d, K - 1 - i) for d in range(M)]) for j in range(N)] for i in range(K)],
        "M2": [[first([(j, M - 1 - i, K - 1 - d) for d in range(K)]) for j in range(N)] for i in range(M)],
        "M3": [[first([(d, M - 1 - j, K - 1 - i) for d in range(N)]) for j in range(M)] for i in range(K)],
        "M4": [[first([(j, d, K - 1 - i) for d in range(M)]) for j in range(N)] for i in range(K)],
        "M5": [[first([(N - 1 - j, M - 1 - i, d) for d in range(K)]) for j in range(N)] for i in range(M)],
    }
    mm["size"] = [N, M, K]
    mm["bounds"] = [[0, 0, 0], [N, M, K]]
    return mm


def silhouette(path, k, png):
    mm = json.load(open(path))["matrix_model"]
    n = mm["size"]
    length = n[(0, 1, 2, 0, 1, 2)[k]]
    w, h, rows = png_read.read(png)
    m = mm["M%d" % k]
    if (len(m), len(m[0])) != (h, w):
        raise SystemExit("the image is %d x %d, the matrix %d x %d" % (w, h, len(m[0]), len(m)))
    return sum(1 for i in range(h) for j in range(w) if (m[i][j] < length) != (rows[i][j] != (255, 0, 255)))


def main():
    if sys.argv[1] == "silhouette":
        print(silhouette(sys.argv[2], int(sys.argv[3]), sys.argv[4]))
        return
    cmd, n, rest = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
    out = rest[-1]
    shape = [cmd] + rest[:-1]
    if cmd == "mask":
        shape = rest[:-1]
    vox = [[[inside(shape, n, x, y, z) for z in range(n)] for y in range(n)] for x in range(n)]
    if cmd == "mask":
        data = bytes(255 if vox[x][y][z] else 0 for z in range(n) for y in range(n) for x in range(n))
        open(out, "wb").write(data)
        return
    json.dump({"name": cmd, "matrix_model": matrices(vox, n)}, open(out, "w"))


main()
