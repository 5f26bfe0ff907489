#!/usr/bin/env python3
"""stl_check.py FILE.stl VOLUME: a binary STL is closed (every edge in exactly two triangles, once each
way) and encloses VOLUME within 0.1 % (VOLUME "-": closed alone). Prints the triangle count and the
volume; exit 1 otherwise."""
import struct
import sys

data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 80)[0]
if len(data) != 84 + 50 * n:
    sys.exit("size %d is not 84 + 50 x %d" % (len(data), n))
edges, vol, index = {}, 0.0, {}
for k in range(n):
    v = struct.unpack_from("<12f", data, 84 + 50 * k)[3:]
    tri = [v[0:3], v[3:6], v[6:9]]
    ids = [index.setdefault(p, len(index)) for p in tri]
    for i in range(3):
        e = (ids[i], ids[(i + 1) % 3])
        edges[e] = edges.get(e, 0) + 1
    a, b, c = tri
    vol += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6
open_edges = sum(1 for (a, b), m in edges.items() if m != 1 or edges.get((b, a)) != 1)
if sys.argv[2] == "-":
    print("%d triangles, volume %.3f, %d unpaired edges" % (n, vol, open_edges))
    sys.exit(0 if open_edges == 0 and n > 0 else 1)
want = float(sys.argv[2])
print("%d triangles, volume %.3f (%+.4f %%), %d unpaired edges" % (n, vol, 100 * (vol - want) / want, open_edges))
sys.exit(0 if open_edges == 0 and abs(vol - want) <= 1e-3 * abs(want) else 1)
