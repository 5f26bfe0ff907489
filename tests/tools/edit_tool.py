#!/usr/bin/python3
"""Helpers of tests/api/edit.sh and the edit bench (standard library only).

  edit_tool.py block N VALUE_IN VALUE_OUT RADIUS OUT         an N^3 int16 block: a ball of VALUE_IN
  edit_tool.py apply VOLUME DIMS REGION BLOCK OUT            VOLUME (int16 raw, DIMS=x,y,z) with BLOCK
                                                             written at REGION=x0,y0,z0,nx,ny,nz
  edit_tool.py same A.stl B.stl                              exit 0 when the two binary STLs hold the
                                                             same triangles (in any order, each turned
                                                             to start at its least corner)
"""
import struct
import sys


def block(n, vin, vout, r, out):
    c = n / 2.0
    vals = [vin if (x - c + 0.3) ** 2 + (y - c - 0.2) ** 2 + (z - c + 0.1) ** 2 < r * r else vout
            for z in range(n) for y in range(n) for x in range(n)]
    with open(out, "wb") as f:
        f.write(struct.pack("<%dh" % len(vals), *vals))


def apply(volume, dims, region, blk, out):
    nx, ny, nz = (int(v) for v in dims.split(","))
    x0, y0, z0, bx, by, bz = (int(v) for v in region.split(","))
    vol = bytearray(open(volume, "rb").read())
    b = open(blk, "rb").read()
    assert len(vol) == 2 * nx * ny * nz and len(b) == 2 * bx * by * bz
    for z in range(bz):
        for y in range(by):
            at = 2 * (x0 + nx * ((y0 + y) + ny * (z0 + z)))
            src = 2 * bx * (y + by * z)
            vol[at:at + 2 * bx] = b[src:src + 2 * bx]
    open(out, "wb").write(vol)


def triangles(path):
    data = open(path, "rb").read()
    n = struct.unpack_from("<I", data, 80)[0]
    tris = []
    for k in range(n):
        v = struct.unpack_from("<9f", data, 84 + 50 * k + 12)
        c = [v[0:3], v[3:6], v[6:9]]
        r = min(range(3), key=lambda i: c[i])
        tris.append(tuple(c[r:] + c[:r]))
    return sorted(tris)


def same(a, b):
    ta, tb = triangles(a), triangles(b)
    differ = sum(1 for p, q in zip(ta, tb) if p != q) + abs(len(ta) - len(tb))
    if differ:
        print("%d of %d/%d triangles differ" % (differ, len(ta), len(tb)))
    return differ == 0


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    if cmd == "block":
        block(int(args[0]), int(args[1]), int(args[2]), float(args[3]), args[4])
    elif cmd == "apply":
        apply(*args)
    elif cmd == "same":
        sys.exit(0 if same(*args) else 1)
    else:
        sys.exit(__doc__)
