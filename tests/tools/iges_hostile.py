#!/usr/bin/env python3
"""iges_hostile.py OUT USES [NEST]: a small IGES part built to cost much (issue 48, finding 2).

A plate whose USES 144s share one 142 -> 102 -> 126. The 126 is a quadratic zigzag of 171 spans
in (u, v) reaching 1e4 domains off the plate, so its chord test halves every span down to the
sampler's deepest level: 2^14 points a span, 2.8 M a use. NEST > 0 nests the composite NEST times,
each level naming the one below twice (2^NEST uses per loop). Used by tests/api/iges_budget.sh and
tests/bench/small_inputs.sh.
"""
import os
import sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import iges_write as w
out, uses = sys.argv[1], int(sys.argv[2])
nest = int(sys.argv[3]) if len(sys.argv) > 3 else 0
K, A = 172, 10000
xs = [round(0.1 + 0.8 * i / (K - 1), 4) for i in range(K - 1)]
pts = [(0.5, 0.5)] + [(x, A if i % 2 else -A) for i, x in enumerate(xs)] + [(0.5, 0.5)]
knots = [0, 0, 0] + list(range(1, K - 1)) + [K - 1] * 3
xyz = [c for x, y in pts for c in (x, y, 0)]
ents = [w.plane(100),                                                                        # 0
        {'type': 126, 'status': 10500,
         'params': [K, 2, 0, 0, 1, 0] + knots + [1] * (K + 1) + xyz + [0, K - 1, 0, 0, 1]}]  # 1
ents.append({'type': 102, 'status': 10500, 'params': [1, ('D', 1)]})                         # 2
for _ in range(nest):
    ents.append({'type': 102, 'status': 10500, 'params': [2, ('D', len(ents) - 1), ('D', len(ents) - 1)]})
ents.append({'type': 142, 'status': 10000, 'params': [0, ('D', 0), ('D', len(ents) - 1), 0, 1]})
loop = len(ents) - 1
ents += [{'type': 144, 'params': [('D', 0), 1, 0, ('D', loop)]} for _ in range(uses)]
w.write(out, ents)
