#!/usr/bin/env python3
"""The Python package's costs, measured (numbers in docs/python.md):

1. Overhead: `Matcher.compute` on a 1-megapixel pair against the same pipeline run in Rust
   (`examples/time_pipeline.rs`: `Plan::run` on the same 16-bit grey images), medians of RUNS runs.
2. Threads: two Python threads matching two pairs against one thread matching both in turn.

    cargo build --release --example time_pipeline
    python crates/python/bench/bench.py target/release/examples/time_pipeline [RUNS]
    python crates/python/bench/bench.py threads [RUNS]      # the thread measurement alone
"""

import json
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

import stereo_depth as sd

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from conftest import scene, write_png  # noqa: E402

rust = sys.argv[1] if len(sys.argv) > 1 else None
threads_only = rust == "threads"
runs = int(sys.argv[2]) if len(sys.argv) > 2 else 9
W, H, MAX = 1152, 868, 128  # 1.0 megapixel

tmp = Path(tempfile.mkdtemp())
left8, right8 = scene(W, H, disparity=30, seed=3)
write_png(tmp / "l.png", left8)
write_png(tmp / "r.png", right8)
left, right = sd.read_image(tmp / "l.png"), sd.read_image(tmp / "r.png")  # uint16, as Rust loads them
m = sd.Matcher(max_disparity=MAX)


def python_medians():
    m.compute(left, right)  # warm up
    wall, inner, binding = [], [], []
    for _ in range(runs):
        t = time.perf_counter()
        m.compute(left, right)
        wall.append((time.perf_counter() - t) * 1000)
        t = time.perf_counter()
        res = m.compute_detailed(left, right)
        total = (time.perf_counter() - t) * 1000
        inner.append(res.timings_ms["total"])
        # Per call: everything outside the library's run (argument checks, views, GIL, output).
        binding.append(total - res.timings_ms["total"])
    return statistics.median(wall), statistics.median(inner), statistics.median(binding)


print(f"pair {W}x{H} ({W * H / 1e6:.2f} MP), max_disparity {MAX}, {runs} runs per median")
rows = []
for round_ in range(0 if threads_only else 3):
    py_wall, py_inner, py_binding = python_medians()
    line = (f"round {round_ + 1}: python compute {py_wall:.1f} ms (library part {py_inner:.1f} ms, "
            f"binding {py_binding:.2f} ms per call)")
    if rust:
        out = subprocess.run([rust, tmp / "l.png", tmp / "r.png", str(MAX), str(runs)], capture_output=True, text=True,
                             check=True)
        r = json.loads(out.stdout)
        line += f", rust Plan::run {r['total_ms']:.1f} ms: overhead {100 * (py_wall / r['total_ms'] - 1):+.1f} %"
        rows.append((py_wall, r["total_ms"]))
    print(line)
if rows:
    py = statistics.median(p for p, _ in rows)
    rs = statistics.median(r for _, r in rows)
    print(f"median of rounds: python {py:.1f} ms, rust {rs:.1f} ms, overhead {100 * (py / rs - 1):+.1f} %")

# Two threads, two pairs.
left_b, right_b = scene(W, H, disparity=20, seed=4)
pairs = [(left8, right8), (left_b, right_b)]
for threads in (1, None):
    matchers = [sd.Matcher(max_disparity=MAX, threads=threads) for _ in pairs]
    for mt, (l, r) in zip(matchers, pairs):
        mt.compute(l, r)
    seq, par, cpu = [], [], []
    for _ in range(max(3, runs // 2)):
        t = time.perf_counter()
        for mt, (l, r) in zip(matchers, pairs):
            mt.compute(l, r)
        seq.append(time.perf_counter() - t)
        t, c = time.perf_counter(), time.process_time()
        workers = [threading.Thread(target=mt.compute, args=p) for mt, p in zip(matchers, pairs)]
        for w in workers:
            w.start()
        for w in workers:
            w.join()
        par.append(time.perf_counter() - t)
        cpu.append((time.process_time() - c) / par[-1])
    s, p = statistics.median(seq) * 1000, statistics.median(par) * 1000
    name = "threads=1 per Matcher" if threads else "threads=None (shared pool)"
    print(f"two pairs, {name}: one thread {s:.0f} ms, two threads {p:.0f} ms: {p / s:.2f}x "
          f"(CPU time / wall time while both ran: {statistics.median(cpu):.2f} cores)")
