"""The GIL is released while matching: other Python threads run meanwhile."""

import threading
import time

import numpy as np

import stereo_depth as sd
from conftest import scene


def test_gil_is_released_while_matching():
    left, right = scene(width=640, height=480, disparity=20)
    m = sd.Matcher(max_disparity=64, threads=1)
    window = {}

    def work():
        window["start"] = time.perf_counter()
        m.compute(left, right)
        window["end"] = time.perf_counter()

    ticks = []
    worker = threading.Thread(target=work)
    worker.start()
    while worker.is_alive():
        ticks.append(time.perf_counter())
    worker.join()
    start, end = window["start"], window["end"]
    assert end - start > 0.02  # long enough to tell
    # Python code ran in this thread while the other one was inside compute. With the GIL held
    # for the whole call, no tick could fall in the middle of it.
    middle = [t for t in ticks if start + 0.25 * (end - start) < t < end - 0.25 * (end - start)]
    assert len(middle) > 100, (len(middle), end - start)


def test_two_threads_two_pairs_same_results():
    pairs = [scene(width=320, height=240, disparity=d, seed=s) for d, s in ((8, 1), (14, 2))]
    matchers = [sd.Matcher(max_disparity=48, threads=1) for _ in pairs]
    expected = [m.compute(*p) for m, p in zip(matchers, pairs)]
    got = [None, None]

    def work(i):
        got[i] = matchers[i].compute(*pairs[i])

    workers = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for w in workers:
        w.start()
    for w in workers:
        w.join()
    for g, e in zip(got, expected):
        assert np.array_equal(g, e, equal_nan=True)
