#!/usr/bin/env python3
"""Rectification against OpenCV (docs/calibration.md).

Usage: opencv-rectify.py STEREO_DEPTH [DATA_DIR]

For synthetic calibrations written in every supported format (OpenCV YAML and XML as
cv2.FileStorage writes them, plain YAML, JSON, ROS camera_info), raw pairs are made from rectified
ones with OpenCV (the inverse of the rectification: undistortPoints + remap), then
`stereo-depth rectify` is compared with OpenCV:

- R1 R2 P1 P2 match cv2.stereoRectify (CALIB_ZERO_DISPARITY, alpha 0 / 0.5 / 1) to 1e-6, and
  cv2.fisheye.stereoRectify (balance 0 / 0.5 / 1) for fisheye lenses;
- the maps match cv2.initUndistortRectifyMap (cv2.fisheye's) within 0.01 px;
- the rectified images match cv2.remap (INTER_LINEAR) within one grey level on average;
- round trip: matching the raw pair through `--calib` keeps bad2 within 1.5 points of matching
  the original rectified pair (shared Middlebury scenes when DATA_DIR is given, else a synthetic
  scene), for the pair command and the batch command (whose maps are computed once).

Prints a table (the one in docs/calibration.md) and exits 1 when a bound is exceeded.
"""

import json
import os
import subprocess
import sys
import tempfile

import cv2
import numpy as np

EXE = os.path.abspath(sys.argv[1])
DATA = sys.argv[2] if len(sys.argv) > 2 else None
FAILURES = []


def check(ok, what):
    if not ok:
        FAILURES.append(what)
        print(f"FAIL: {what}")


def run(*args):
    result = subprocess.run([EXE, *map(str, args)], capture_output=True, text=True)
    if result.returncode != 0:
        raise SystemExit(f"stereo-depth {' '.join(map(str, args))} failed:\n{result.stderr}")
    return result.stdout


def rig(size, seed, strong=False):
    """A plausible stereo calibration for images of `size` (T in metres)."""
    rng = np.random.default_rng(seed)
    w, h = size
    f = 0.9 * w
    K = []
    for _ in range(2):
        K.append(np.array([[f * rng.uniform(0.98, 1.02), 0, w / 2 + rng.uniform(-8, 8)],
                           [0, f * rng.uniform(0.98, 1.02), h / 2 + rng.uniform(-8, 8)], [0, 0, 1.0]]))
    k1 = -0.32 if strong else -0.12
    D = [np.array([k1 + rng.uniform(-0.02, 0.02), 0.1 * abs(k1) + rng.uniform(-0.01, 0.01),
                   rng.uniform(-1e-3, 1e-3), rng.uniform(-1e-3, 1e-3), rng.uniform(-0.01, 0.01)])
         for _ in range(2)]
    R = cv2.Rodrigues(rng.uniform(-0.02, 0.02, 3))[0]
    T = np.array([[-0.12], [rng.uniform(-0.003, 0.003)], [rng.uniform(-0.003, 0.003)]])
    return K[0], D[0], K[1], D[1], R, T


def mat_text(m):
    return "[" + ", ".join(repr(float(v)) for v in np.asarray(m).ravel()) + "]"


def write_formats(folder, size, K1, D1, K2, D2, R, T):
    """The calibration in every supported format; returns {name: path}."""
    paths = {}
    for name, ext in [("opencv-yaml", "yaml"), ("opencv-xml", "xml")]:
        path = os.path.join(folder, f"stereo.{ext}")
        fs = cv2.FileStorage(path, cv2.FILE_STORAGE_WRITE)
        for key, value in dict(K1=K1, D1=D1, K2=K2, D2=D2, R=R, T=T).items():
            fs.write(key, value)
        fs.write("imageSize", size)
        fs.release()
        paths[name] = path
    path = os.path.join(folder, "plain.yaml")
    with open(path, "w") as f:
        f.write(f"# plain YAML\nimage_width: {size[0]}\nimage_height: {size[1]}\n")
        f.write(f"K1: {[list(map(float, r)) for r in K1]}\nD1: {mat_text(D1)}\n")
        f.write(f"K2: {[list(map(float, r)) for r in K2]}\nD2: {mat_text(D2)}\n")
        f.write(f"R: {mat_text(cv2.Rodrigues(R)[0])}  # a rotation vector\nT: {mat_text(T)}\n")
    paths["plain-yaml"] = path
    path = os.path.join(folder, "stereo.json")
    with open(path, "w") as f:
        json.dump(dict(imageSize=list(size), K1=K1.tolist(), D1=D1.tolist(), K2=K2.tolist(),
                       D2=D2.tolist(), R=R.tolist(), T=T.ravel().tolist()), f, indent=1)
    paths["json"] = path
    # ROS: what camera_calibration writes after stereo calibration (its own alpha 0 rectification).
    R1, R2, P1, P2, *_ = cv2.stereoRectify(K1, D1, K2, D2, size, R, T, flags=cv2.CALIB_ZERO_DISPARITY, alpha=0)
    ros = os.path.join(folder, "ros")
    os.makedirs(ros, exist_ok=True)
    for side, K, D, Rr, P in [("left", K1, D1, R1, P1), ("right", K2, D2, R2, P2)]:
        with open(os.path.join(ros, f"{side}.yaml"), "w") as f:
            f.write(f"image_width: {size[0]}\nimage_height: {size[1]}\ncamera_name: stereo/{side}\n")
            for key, m in [("camera_matrix", K), ("distortion_coefficients", D.reshape(1, -1)),
                           ("rectification_matrix", Rr), ("projection_matrix", P)]:
                m = np.atleast_2d(m)
                f.write(f"{key}:\n  rows: {m.shape[0]}\n  cols: {m.shape[1]}\n  data: {mat_text(m)}\n")
                if key == "camera_matrix":
                    f.write("distortion_model: plumb_bob\n")
    paths["ros"] = os.path.join(ros, "left.yaml")
    return paths


def opencv_rectification(fmt, size, alpha, K1, D1, K2, D2, R, T):
    if fmt == "ros":  # the files' own R and P
        alpha = 0
    return cv2.stereoRectify(K1, D1, K2, D2, size, R, T, flags=cv2.CALIB_ZERO_DISPARITY, alpha=alpha)[:4]


def raw_from_rectified(image, K, D, Rk, P):
    """The raw view whose rectification (K, D, Rk, P) is `image`: each raw pixel's rectified
    position, sampled from the rectified image."""
    h, w = image.shape[:2]
    u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pts = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-9)
    if hasattr(cv2, "undistortPointsIter"):  # OpenCV 4
        rect = cv2.undistortPointsIter(pts, K, D, Rk, P, crit)
    else:
        rect = cv2.undistortPoints(pts, K, D, R=Rk, P=P, criteria=crit)
    rect = rect.reshape(h, w, 2).astype(np.float32)
    return cv2.remap(image, rect[..., 0], rect[..., 1], cv2.INTER_CUBIC, borderMode=cv2.BORDER_CONSTANT)


def synthetic_scene(folder):
    """A textured scene with two fronto-parallel planes (disparity 12 and 24), 8-bit."""
    rng = np.random.default_rng(7)
    w, h = 480, 360
    tex = cv2.GaussianBlur(rng.uniform(0, 255, (h, w + 64)).astype(np.float32), (0, 0), 1.2)
    tex = cv2.normalize(tex, None, 0, 255, cv2.NORM_MINMAX)
    disp = np.full((h, w), 12.0, np.float32)
    disp[100:260, 150:330] = 24.0
    xs = np.arange(w)[None, :] - disp + 32
    right = tex[:, 32:32 + w]
    left = cv2.remap(tex, xs.astype(np.float32), np.repeat(np.arange(h, dtype=np.float32)[:, None], w, 1),
                     cv2.INTER_LINEAR)
    # Occluded pixels are not scored.
    gt = (disp * 4).astype(np.uint8)
    for name, img in [("left.png", left), ("right.png", right), ("gt.png", gt)]:
        cv2.imwrite(os.path.join(folder, name), np.clip(img, 0, 255).astype(np.uint8))
    return dict(scene="synthetic", dir=folder, left="left.png", right="right.png", gt="gt.png", scale=4, ndisp=32)


def scenes(tmp):
    if DATA and os.path.exists(os.path.join(DATA, "scenes.tsv")):
        rows = [line.rstrip("\n").split("\t") for line in open(os.path.join(DATA, "scenes.tsv"))]
        header = rows[0]
        out = []
        for row in rows[1:]:
            r = dict(zip(header, row))
            if r["scene"] in ("cones", "teddy"):
                out.append(dict(scene=r["scene"], dir=os.path.join(DATA, r["scene"]), left=r["left"],
                                right=r["right"], gt=r["gt_left"], scale=float(r["gt_scale"]),
                                ndisp=int(r["suggested_ndisp"])))
        if out:
            return out
    folder = os.path.join(tmp, "synthetic")
    os.makedirs(folder, exist_ok=True)
    return [synthetic_scene(folder)]


def bad2(disparity, scene):
    out = run("eval", disparity, os.path.join(scene["dir"], scene["gt"]), "--gt-scale", scene["scale"], "--json")
    stats = json.loads(out)
    stats = stats.get("metrics", stats)
    for key in ("bad2", "bad_2", "bad2_percent"):
        if key in stats:
            return float(stats[key])
    raise SystemExit(f"no bad2 in eval --json: {out[:300]}")


def main():
    table = []
    with tempfile.TemporaryDirectory() as tmp:
        # 1. Matrices, maps and images against OpenCV, every format, three alphas, two rigs.
        grey = cv2.imread(os.path.join(scenes(tmp)[0]["dir"], scenes(tmp)[0]["left"]), cv2.IMREAD_GRAYSCALE)
        for seed, strong in [(1, False), (2, True)]:
            size = (grey.shape[1], grey.shape[0])
            K1, D1, K2, D2, R, T = rig(size, seed, strong)
            folder = os.path.join(tmp, f"rig{seed}")
            os.makedirs(folder)
            raw_l = os.path.join(folder, "raw_left.png")
            raw_r = os.path.join(folder, "raw_right.png")
            cv2.imwrite(raw_l, grey)
            cv2.imwrite(raw_r, np.roll(grey, 7, axis=1))
            for fmt, path in write_formats(folder, size, K1, D1, K2, D2, R, T).items():
                for alpha in ([0.0] if fmt == "ros" else [0.0, 0.5, 1.0]):
                    out = os.path.join(folder, f"out-{fmt}-{alpha}")
                    run("rectify", raw_l, raw_r, "--calib", path, "-o", out, "--alpha", alpha, "--maps", "-q")
                    cv = opencv_rectification(fmt, size, alpha, K1, D1, K2, D2, R, T)
                    fs = cv2.FileStorage(os.path.join(out, "rectification.yaml"), cv2.FILE_STORAGE_READ)
                    mine = [fs.getNode(k).mat() for k in ("R1", "R2", "P1", "P2")]
                    mat_err = max(float(np.abs(a - b).max()) for a, b in zip(mine, cv))
                    map_err, img_err = 0.0, 0.0
                    for side, K, D, (Rk, P), raw, im in [("left", K1, D1, cv[0::2], raw_l, "im0.png"),
                                                         ("right", K2, D2, cv[1::2], raw_r, "im1.png")]:
                        mx, my = cv2.initUndistortRectifyMap(K, D, Rk, P, size, cv2.CV_32FC1)
                        ox = cv2.imread(os.path.join(out, f"{side}_map_x.pfm"), cv2.IMREAD_UNCHANGED)
                        oy = cv2.imread(os.path.join(out, f"{side}_map_y.pfm"), cv2.IMREAD_UNCHANGED)
                        map_err = max(map_err, float(np.abs(ox - mx).max()), float(np.abs(oy - my).max()))
                        ref = cv2.remap(cv2.imread(raw, cv2.IMREAD_GRAYSCALE), mx, my, cv2.INTER_LINEAR)
                        got = cv2.imread(os.path.join(out, im), cv2.IMREAD_UNCHANGED)
                        img_err = max(img_err, float(np.abs(got.astype(np.float64) - ref).mean()))
                    table.append((f"rig {seed}{' (strong)' if strong else ''}", fmt, alpha, mat_err, map_err, img_err))
                    check(mat_err < 1e-6, f"{fmt} alpha {alpha}: matrices differ by {mat_err:g}")
                    check(map_err < 0.01, f"{fmt} alpha {alpha}: maps differ by {map_err:g} px")
                    check(img_err < 1.0, f"{fmt} alpha {alpha}: images differ by {img_err:g} grey levels")

        # Equidistant (fisheye) lenses in ROS files (their own R and P, from cv2.fisheye.stereoRectify):
        # maps against cv2.fisheye.initUndistortRectifyMap.
        size = (grey.shape[1], grey.shape[0])
        f = 0.45 * size[0]
        Kf = [np.array([[f * s, 0, size[0] / 2 + dx], [0, f * s, size[1] / 2 + dy], [0, 0, 1.0]])
              for s, dx, dy in [(1.0, 3.0, -2.0), (1.01, -4.0, 3.0)]]
        Df = [np.array([[0.05], [-0.01], [0.003], [-0.0005]]), np.array([[0.045], [-0.008], [0.002], [-0.0004]])]
        Rf = cv2.Rodrigues(np.array([0.01, -0.02, 0.005]))[0]
        Tf = np.array([[-0.1], [0.002], [-0.001]])
        R1f, R2f, P1f, P2f, _ = cv2.fisheye.stereoRectify(Kf[0], Df[0], Kf[1], Df[1], size, Rf, Tf,
                                                        flags=cv2.CALIB_ZERO_DISPARITY, balance=0.0)
        folder = os.path.join(tmp, "fisheye")
        os.makedirs(folder)
        for side, K, D, Rk, P in [("left", Kf[0], Df[0], R1f, P1f), ("right", Kf[1], Df[1], R2f, P2f)]:
            with open(os.path.join(folder, f"{side}.yaml"), "w") as fh:
                fh.write(f"image_width: {size[0]}\nimage_height: {size[1]}\ndistortion_model: equidistant\n")
                for key, m in [("camera_matrix", K), ("distortion_coefficients", D.reshape(1, -1)),
                               ("rectification_matrix", Rk), ("projection_matrix", P)]:
                    m = np.atleast_2d(m)
                    fh.write(f"{key}:\n  rows: {m.shape[0]}\n  cols: {m.shape[1]}\n  data: {mat_text(m)}\n")
        # The same rig as an OpenCV file marked `distortion_model: fisheye`: the rectification is
        # computed (cv2.fisheye.stereoRectify, --alpha as its balance).
        fs = cv2.FileStorage(os.path.join(folder, "fisheye.yaml"), cv2.FILE_STORAGE_WRITE)
        for key, value in dict(K1=Kf[0], D1=Df[0], K2=Kf[1], D2=Df[1], R=Rf, T=Tf).items():
            fs.write(key, value)
        fs.write("distortion_model", "fisheye")
        fs.release()
        raw_l = os.path.join(folder, "raw_left.png")
        cv2.imwrite(raw_l, grey)
        for fmt, path, alphas in [("ros (equidistant)", os.path.join(folder, "left.yaml"), [0.0]),
                                  ("opencv-yaml, fisheye", os.path.join(folder, "fisheye.yaml"), [0.0, 0.5, 1.0])]:
            for alpha in alphas:
                out = os.path.join(folder, f"out-{len(table)}")
                run("rectify", raw_l, raw_l, "--calib", path, "-o", out, "--maps", "-q", "--alpha", alpha)
                cv = cv2.fisheye.stereoRectify(Kf[0], Df[0], Kf[1], Df[1], size, Rf, Tf,
                                               flags=cv2.CALIB_ZERO_DISPARITY, balance=alpha)[:4]
                mat_err = None
                if fmt.startswith("opencv"):
                    fs = cv2.FileStorage(os.path.join(out, "rectification.yaml"), cv2.FILE_STORAGE_READ)
                    mat_err = max(float(np.abs(fs.getNode(k).mat() - m).max())
                                  for k, m in zip(("R1", "R2", "P1", "P2"), cv))
                    check(mat_err < 1e-6, f"fisheye {fmt} alpha {alpha}: matrices differ by {mat_err:g}")
                map_err, img_err = 0.0, 0.0
                for side, K, D, Rk, P, im in [("left", Kf[0], Df[0], cv[0], cv[2], "im0.png"),
                                              ("right", Kf[1], Df[1], cv[1], cv[3], "im1.png")]:
                    mx, my = cv2.fisheye.initUndistortRectifyMap(K, D, Rk, P, size, cv2.CV_32FC1)
                    ox = cv2.imread(os.path.join(out, f"{side}_map_x.pfm"), cv2.IMREAD_UNCHANGED)
                    oy = cv2.imread(os.path.join(out, f"{side}_map_y.pfm"), cv2.IMREAD_UNCHANGED)
                    map_err = max(map_err, float(np.abs(ox - mx).max()), float(np.abs(oy - my).max()))
                    ref = cv2.remap(grey, mx, my, cv2.INTER_LINEAR)
                    got = cv2.imread(os.path.join(out, im), cv2.IMREAD_UNCHANGED)
                    img_err = max(img_err, float(np.abs(got.astype(np.float64) - ref).mean()))
                table.append(("fisheye", fmt, alpha if fmt.startswith("opencv") else "-", mat_err, map_err, img_err))
                check(map_err < 0.01, f"fisheye {fmt} alpha {alpha}: maps differ by {map_err:g} px")
                check(img_err < 1.0, f"fisheye {fmt} alpha {alpha}: images differ by {img_err:g} grey levels")

        print("| rig | format | alpha | R1 R2 P1 P2 max abs diff | maps max diff (px) | image mean abs diff (grey levels) |")
        print("|---|---|---|---|---|---|")
        for rig_name, fmt, alpha, m, p, i in table:
            matrices = "(the file's)" if m is None else f"{m:.1e}"
            print(f"| {rig_name} | {fmt} | {alpha} | {matrices} | {p:.1e} | {i:.3f} |")

        # 2. Round trip: raw pairs made from rectified scenes, matched through --calib.
        print()
        print("| scene | lens | format | command | bad2 original | bad2 round trip | difference |")
        print("|---|---|---|---|---|---|---|")
        for scene in scenes(tmp):
            left = cv2.imread(os.path.join(scene["dir"], scene["left"]), cv2.IMREAD_COLOR)
            right = cv2.imread(os.path.join(scene["dir"], scene["right"]), cv2.IMREAD_COLOR)
            size = (left.shape[1], left.shape[0])
            folder = os.path.join(tmp, "rt-" + scene["scene"])
            os.makedirs(folder)
            ndisp = ["--max-disparity", scene["ndisp"]]
            base = os.path.join(folder, "orig.pfm")
            run(os.path.join(scene["dir"], scene["left"]), os.path.join(scene["dir"], scene["right"]),
                "--disparity", base, "-q", *ndisp)
            original = bad2(base, scene)
            # A typical lens (k1 about -0.12) is the bound; a strongly distorting one (k1 about
            # -0.32: its corners lose resolution in the raw view) is reported.
            for strength, strong in [("moderate", False), ("strong", True)]:
                K1, D1, K2, D2, R, T = rig(size, 3, strong=strong)
                sub = os.path.join(folder, strength)
                os.makedirs(sub)
                paths = write_formats(sub, size, K1, D1, K2, D2, R, T)
                # The raw pair of this rig (every format gives the same alpha-0 rectification: the
                # ROS files hold the one cv2.stereoRectify computes); two copies for the batch.
                R1, R2, P1, P2 = opencv_rectification("opencv-yaml", size, 0.0, K1, D1, K2, D2, R, T)
                batch_in = os.path.join(sub, "raw")
                for copy in ("a", "b"):
                    os.makedirs(os.path.join(batch_in, copy))
                    cv2.imwrite(os.path.join(batch_in, copy, "im0.png"), raw_from_rectified(left, K1, D1, R1, P1))
                    cv2.imwrite(os.path.join(batch_in, copy, "im1.png"), raw_from_rectified(right, K2, D2, R2, P2))
                raw_l, raw_r = os.path.join(batch_in, "a", "im0.png"), os.path.join(batch_in, "a", "im1.png")
                for fmt, path in paths.items():
                    if strong and fmt not in ("opencv-yaml", "ros"):
                        continue
                    disp = os.path.join(sub, f"{fmt}.pfm")
                    run(raw_l, raw_r, "--calib", path, "--disparity", disp, "-q", *ndisp)
                    got = bad2(disp, scene)
                    print(f"| {scene['scene']} | {strength} | {fmt} | pair | {original:.2f} | {got:.2f} | {got - original:+.2f} |")
                    if strong:
                        continue
                    check(got - original <= 1.5, f"{scene['scene']} {fmt}: round-trip bad2 {got:.2f} vs {original:.2f}")
                    # One calibration, many pairs: the batch command computes the maps once.
                    out = os.path.join(sub, f"depth-{fmt}")
                    text = run("batch", batch_in, "--calib", path, "--out", out, "--disparity", *ndisp)
                    check("maps computed once" in text, f"batch did not report computing the maps once: {text[-400:]}")
                    for copy in ("a", "b"):
                        pfm = os.path.join(out, copy, "im0.disparity.pfm")
                        check(os.path.exists(pfm), f"batch wrote no {pfm}")
                        if os.path.exists(pfm):
                            got = bad2(pfm, scene)
                            check(got - original <= 1.5, f"batch {scene['scene']} {fmt}: bad2 {got:.2f} vs {original:.2f}")
                    print(f"| {scene['scene']} | {strength} | {fmt} | batch (2 pairs, maps once) | {original:.2f} | {got:.2f} | {got - original:+.2f} |")

    if FAILURES:
        print(f"\n{len(FAILURES)} check(s) failed")
        sys.exit(1)
    print("\nall rectification checks passed")


if __name__ == "__main__":
    main()
