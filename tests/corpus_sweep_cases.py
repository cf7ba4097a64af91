"""The bad-input corpus's cases for the multi-material and batch commands, and a sweep over
every command's fields (same form as corpus_cases.CASES)."""

import os

import cv2
import numpy as np
from corpus_inputs import (
    batch_argv,
    beside,
    black_png,
    captures,
    empty,
    labels_png,
    links_to,
    marked_folder,
    marked_holding,
    merl_body,
    merl_copy,
    model_edited,
    model_with_param,
    model_with_params,
    no_theta_d_0,
    npz_bytes,
    one_channel_exr,
    out_path,
    png_bomb,
    render_argv,
    rgb_exr,
    run_argv,
    scene_copy,
    scene_with_file,
    set_field,
    tiny_scene,
    truncated,
    two_tables,
    user_folder,
    with_faces,
    write,
)

SWEEP_CASES = [
    ("segment", "materials 0", lambda w, t: ["segment", str(w.scene), "--out", out_path(t, "l.png"),
                                             "--materials", "0"], "--materials"),
    ("segment", "materials more than the pixels allow", lambda w, t: [
        "segment", str(tiny_scene(t, 0.03)), "--out", out_path(t, "l.png"), "--materials", "8"],
     "--materials"),
    ("segment", "no object pixel", lambda w, t: ["segment", str(tiny_scene(t, 0.004)), "--out",
                                                 out_path(t, "l.png")], "flash0.exr"),
    ("segment", "albedo's sidecar is the labels'", lambda w, t: [
        "segment", str(w.scene), "--out", out_path(t, "l.png"), "--albedo", out_path(t, "l.exr")],
     "l.json"),
    ("segment", "out is scene.png (its sidecar is scene.json)", lambda w, t: [
        "segment", str(w.scene), "--out", str(w.scene / "scene.png")], "scene.json"),
    ("extract", "labels wrong size", lambda w, t: [
        "extract", str(w.scene), "--labels", str(write(t, "l.png", b"")), "--out", out_path(t)],
     "l.png"),
    ("extract", "labels is a folder", lambda w, t: [
        "extract", str(w.scene), "--labels", str(empty(t)), "--out", out_path(t)], "empty"),
    ("extract", "labels a PNG of 40000x40000", lambda w, t: [
        "extract", str(w.scene), "--labels", str(write(t, "l.png", png_bomb())), "--out",
        out_path(t)], "l.png"),
    ("extract", "labels float TIFF", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, "l.tif", 1, dtype=np.float32)),
        "--out", out_path(t)], "l.tif"),
    ("extract", "labels {1, 3}", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, value=lambda a: a * 2 - (
            a > 0))), "--out", out_path(t)], "labels.png"),
    ("extract", "labels JPEG (named .png)", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, "l.jpg", dtype=np.uint8).rename(
            t / "l.png")), "--out", out_path(t)], "l.png"),
    ("extract", "labels JPEG 2000", lambda w, t: [  # decodes to one channel: only its bytes tell
        "extract", str(w.scene), "--labels", str(labels_png(w, t, "l.jp2", dtype=np.uint8)),
        "--out", out_path(t)], "l.jp2"),
    ("extract", "labels a JPEG-compressed TIFF", lambda w, t: [  # one channel: only its tags tell
        "extract", str(w.scene), "--labels", str(labels_png(w, t, "l.tif", dtype=np.uint8, params=(
            cv2.IMWRITE_TIFF_COMPRESSION, 7))), "--out", out_path(t)], "l.tif"),
    ("extract", "labels unreadable", lambda w, t: [  # a regular file whose read fails (EIO)
        "extract", str(w.scene), "--labels", "/proc/self/mem", "--out", out_path(t)], "mem"),
    ("extract", "labels RGB", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, value=lambda a: np.dstack(
            [a] * 3), dtype=np.uint8)), "--out", out_path(t)], "labels.png"),
    ("extract", "labels all zero", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t, value=lambda a: 0 * a)),
        "--out", out_path(t)], "labels.png"),
    ("extract", "out is someone's folder", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t)), "--out", str(user_folder(t))],
     "mine"),
    ("extract", "labelled earlier output without --force", lambda w, t: [
        "extract", str(w.scene), "--labels", str(labels_png(w, t)), "--out", str(marked_folder(t))],
     "old"),
    ("render", "labels empty (read as not given)", lambda w, t: render_argv(
        w.scene, w.brdf, out_path(t), "--labels", ""), "--labels"),
    ("evaluate", "test-dir empty (read as not given)", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--test-dir", "", "--out", out_path(t)],
     "--test-dir"),
    ("render", "only commas in --brdf", lambda w, t: render_argv(w.scene, ",,", out_path(t)), "--brdf"),
    ("render", "an empty item in --brdf", lambda w, t: render_argv(
        w.scene, f"{w.brdf},,{w.brdf}", out_path(t), "--labels", str(labels_png(w, t))), "--brdf"),
    ("render", "more tables than labels", lambda w, t: render_argv(
        w.scene, f"{two_tables(w)},{w.brdf}", out_path(t), "--labels", str(labels_png(w, t))),
     "labels.png"),
    ("render", "label faces of another mesh", lambda w, t: render_argv(
        w.scene, two_tables(w), out_path(t), "--labels", str(with_faces(labels_png(w, t), np.ones(
            7, np.int32)))), "labels.faces.npy"),
    ("render", "label faces an empty file", lambda w, t: render_argv(
        w.scene, two_tables(w), out_path(t), "--labels", str(beside(labels_png(w, t), ".faces.npy",
                                                              b""))), "labels.faces.npy"),
    ("render", "label faces an .npz archive", lambda w, t: render_argv(
        w.scene, two_tables(w), out_path(t), "--labels", str(beside(labels_png(w, t), ".faces.npy",
                                                              npz_bytes(t)))),
     "labels.faces.npy"),
    ("render", "albedo faces an empty file", lambda w, t: render_argv(
        w.scene, w.brdf, out_path(t), "--albedo", str(beside(rgb_exr(t), ".faces.npy", b""))),
     "albedo.faces.npy"),
    ("render", "albedo faces an .npz archive", lambda w, t: render_argv(
        w.scene, w.brdf, out_path(t), "--albedo", str(beside(rgb_exr(t), ".faces.npy",
                                                         npz_bytes(t)))), "albedo.faces.npy"),
    ("render", "albedo floors an integer of 400 digits", lambda w, t: render_argv(
        w.scene, w.brdf, out_path(t), "--albedo", str(beside(rgb_exr(t), ".json", '{"floors": [[1' +
                                                         "0" * 400 + ', 1, 1]]}'))),
     "albedo.json"),
    ("render", "--force onto a folder holding a listed table", lambda w, t: render_argv(
        w.scene, f"{w.brdf},{marked_holding(t, w.brdf) / w.brdf.name}", t / "old", "--labels",
        str(labels_png(w, t)), "--force"), "old"),
    ("render", "--force onto a folder holding the labels", lambda w, t: render_argv(
        w.scene, two_tables(w), t / "old", "--labels",
        str(marked_holding(t, labels_png(w, t)) / "labels.png"), "--force"), "old"),
    ("render", "albedo of one channel", lambda w, t: render_argv(
        w.scene, w.brdf, out_path(t), "--albedo", str(one_channel_exr(t))), "albedo.exr"),
    ("run", "materials abc", lambda w, t: run_argv(w.scene, out_path(t), "--materials", "abc"),
     "--materials"),
    ("run", "spp 10**11 (out of memory)", lambda w, t: run_argv(w.scene, out_path(t)) + [
        "--spp", str(10 ** 11)], "--spp"),
    ("run", "spp not a number (argparse, one line)", lambda w, t: run_argv(w.scene, out_path(t)) + [
        "--spp", "x"], "--spp"),
    ("batch", "empty folder", lambda w, t: batch_argv(empty(t), out_path(t)), "empty"),
    ("batch", "out empty", lambda w, t: batch_argv(captures(w, t, "a"), ""), "--out"),
    ("batch", "workers abc", lambda w, t: batch_argv(captures(w, t, "a"), out_path(t), "--workers",
                                                 "abc"), "--workers"),
    ("batch", "materials 0", lambda w, t: batch_argv(captures(w, t, "a"), out_path(t), "--materials",
                                                 "0"), "--materials"),
    ("batch", "scheduler with nothing listening", lambda w, t: batch_argv(
        captures(w, t, "a"), out_path(t), "--scheduler", "tcp://127.0.0.1:1"), "--scheduler"),
    ("batch", "scheduler empty", lambda w, t: batch_argv(captures(w, t, "a"), out_path(t),
                                                     "--scheduler", ""), "--scheduler"),
    ("batch", "out is someone's folder", lambda w, t: batch_argv(captures(w, t, "a"), user_folder(t)),
     "mine"),
    ("batch", "model truncated", lambda w, t: batch_argv(captures(w, t, "a"), out_path(t), "--methods",
                                                     "pca", "--model", str(write(
                                                         t, "m.npz", truncated(w.model, 0.7)))),
     "m.npz"),
    ("batch", "out holds someone's summary.md", lambda w, t: batch_argv(
        captures(w, t, "a"), write(empty(t), "summary.md", "my notes").parent), "empty"),
    ("batch", "a capture named logs", lambda w, t: batch_argv(captures(w, t, "logs"), out_path(t)),
     "logs"),
    ("train", "three tables (a fifth is held out)", lambda w, t: [
        "train", "--merl-dir", str(w.merl_dir), "--out", out_path(t, "m.npz")], "merl"),
    ("train", "the same folder twice", lambda w, t: [
        "train", "--merl-dir", str(w.merl_dir), "--merl-dir", str(w.merl_dir) + os.sep, "--out",
        out_path(t, "m.npz")], "given twice"),
    ("evaluate", "test-dir with --workers and --scheduler", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--test-dir", str(w.merl_dir), "--out",
        out_path(t), "--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--workers"),
    ("evaluate", "experiments 0", lambda w, t: ["evaluate", "--merl-dir", str(w.merl_dir),
                                                "--out", out_path(t), "--experiments", "0"],
     "--experiments"),
    # a local cluster of 100000 processes (it forked until the machine gave out)
    ("evaluate", "workers 100000", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--out", out_path(t), "--workers", "100000"],
     "--workers"),
    ("batch", "workers 100000", lambda w, t: batch_argv(captures(w, t, "a", "b"), out_path(t),
                                                    "--workers", "100000"), "--workers"),
    ("train", "seed -1 (a traceback from numpy)", lambda w, t: [
        "train", "--merl-dir", str(merl_copy(w, t)), "--merl-dir", str(write(empty(t),
        "x.binary", w.brdf.read_bytes()[:12] + np.full(90 * 90 * 180 * 3, 0.01).tobytes()
        ).parent), "--out", out_path(t, "m.npz"), "--seed=-1"], "--seed"),
    ("train", "seed 2**32 (a traceback from scikit-learn's uint32 random_state)", lambda w, t: [
        "train", "--merl-dir", str(merl_copy(w, t)), "--merl-dir", str(write(empty(t),
        "x.binary", w.brdf.read_bytes()[:12] + np.full(90 * 90 * 180 * 3, 0.01).tobytes()
        ).parent), "--out", out_path(t, "m.npz"), f"--seed={2 ** 32}"], "--seed"),
    ("evaluate", "experiments 10**9 (it hung drawing the splits)", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--out", out_path(t), "--experiments",
        str(10 ** 9)], "--experiments"),
    # outputs no file can be made at (tracebacks from mkstemp / mkdtemp)
    ("merl-slice", "out in /proc", lambda w, t: ["merl-slice", str(w.brdf), "--out",
                                                "/proc/flashbrdf-s.csv"], "/proc/flashbrdf-s.csv"),
    ("merl-slice", "out a name of 300 bytes", lambda w, t: [
        "merl-slice", str(w.brdf), "--out", str(t / ("a" * 300 + ".csv"))], "a" * 40),
    ("compare", "out a name of 300 bytes", lambda w, t: [
        "compare", str(w.pred), str(w.ref), "--out", str(t / ("a" * 300))], "a" * 40),
    ("render", "out in /proc", lambda w, t: render_argv(w.scene, w.brdf, "/proc/flashbrdf-out"),
     "/proc/flashbrdf-out"),
    # damaged model hyperparameters (tracebacks)
    ("infer", "model params of pca not an object", lambda w, t: [
        "infer", "--method", "pca", "--model", str(model_with_params(w, t, {"pca": "x"})),
        "--slice", str(w.slice), "--out", out_path(t, "b.binary")], "model.npz"),
    ("infer", "model params with an unknown hyperparameter", lambda w, t: [
        "infer", "--method", "noll", "--model", str(model_with_params(w, t, {"noll": {"k": 1}})),
        "--slice", str(w.slice), "--out", out_path(t, "b.binary")], "model.npz"),
    *[("infer", f"model params {method}.{key} = {value!r} ({why})",
       lambda w, t, method=method, key=key, value=value: [
           "infer", "--method", method, "--model", str(model_with_param(w, t, method, key, value)),
           "--slice", str(w.slice), "--out", out_path(t, "b.binary")],
       f"params['{method}']['{key}']")
      for method, key, value, why in (
          ("dsgplvm", "feature_space", "xyz", "a ValueError traceback"),
          ("dsgplvm", "calibration", "abc", "a traceback"),
          ("dsgplvm", "calibration", -1, "negative variances, exit 0"),
          ("ashikhmin", "r0", -3, "28,062 bins written as no data, exit 0"),
          ("ashikhmin", "r0", 0, "a table up to 2.2e24 1/sr, exit 0"))],
    ("infer", "model slices of inf (noll: a traceback)", lambda w, t: [
        "infer", "--method", "noll", "--model", str(model_edited(
            w, t, "slices", lambda a: np.full_like(a, np.inf))), "--slice", str(w.slice),
        "--out", out_path(t, "b.binary")], "model.npz"),
    ("infer", "model tables_2d all NaN (a table of NaN, exit 0)", lambda w, t: [
        "infer", "--method", "pca", "--model", str(model_edited(
            w, t, "tables_2d", lambda a: np.full_like(a, np.nan))), "--slice", str(w.slice),
        "--out", out_path(t, "b.binary")], "model.npz"),
    # one table under several names (train: a LinAlgError traceback)
    ("train", "five links to one table", lambda w, t: [
        "train", "--merl-dir", str(links_to(empty(t), w.brdf, 5)), "--out", out_path(t, "m.npz")],
     "t1.binary"),
    ("train", "a table with no data at theta_d = 0 (a LinAlgError traceback)", lambda w, t: [
        "train", "--merl-dir", str(w.merl_dir), "--merl-dir",
        str(write(empty(t), "m.binary", merl_body(w, no_theta_d_0)).parent), "--out",
        out_path(t, "m.npz")], "m.binary"),
    ("merl-slice", "no data at theta_d = 0 (an empty slice, exit 0)", lambda w, t: [
        "merl-slice", str(write(t, "m.binary", merl_body(w, no_theta_d_0))), "--out",
        out_path(t, "s.csv")], "m.binary"),
    # stored 1e27 is ~7e23 1/sr: under MERL's 1e30 stored, past the 1e20 1/sr slice readers take
    ("merl-slice", "values of 7e23 1/sr (a slice infer refuses, exit 0)", lambda w, t: [
        "merl-slice", str(write(t, "m.binary", merl_body(
            w, lambda body: np.where(body >= 0, 1e27, body)))), "--out", out_path(t, "s.csv")],
     "m.binary"),
    ("train", "a table of 7e23 1/sr (its slice is no BRDF infer reads)", lambda w, t: [
        "train", "--merl-dir", str(w.merl_dir), "--merl-dir", str(write(empty(t), "m.binary",
        merl_body(w, lambda body: np.where(body >= 0, 1e27, body))).parent), "--out",
        out_path(t, "m.npz")], "m.binary"),
    # compare over no pixel (every metric null, exit 0)
    ("compare", "both images black", lambda w, t: [
        "compare", str(rgb_exr(t, value=0.0)), str(rgb_exr(t, "r.exr", value=0.0)), "--out",
        out_path(t)], "r.exr"),
    ("compare", "mask of no pixel", lambda w, t: [
        "compare", str(w.pred), str(w.ref), "--mask", str(black_png(t)), "--out", out_path(t)],
     "m.png"),
    # factors that turned float32 photos and rays to 0 or inf (a slice of zeros, exit 0)
    ("extract", "photos[0].scale 1e308", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("photos", 0, "scale"), 1e308))), "--out", out_path(t, "s.csv")],
     "photos[0].scale"),
    ("extract", "intensity_rgb 1e308", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("photos", 0, "light", "intensity_rgb"), [1e308] * 3))), "--out",
        out_path(t, "s.csv")], "photos[0].light.intensity_rgb"),
    ("extract", "exposure_s 1e-320", lambda w, t: ["extract", str(scene_copy(
        w, t, lambda d: d["photos"][0].update(file=None, brackets=[
            {"file": "flash0.exr", "exposure_s": 1e-320}]))), "--out", out_path(t, "s.csv")],
     "photos[0].brackets[0].exposure_s"),
    ("extract", "camera.fx 1e308 (overflow warnings, exit 0)", lambda w, t: ["extract", str(
        scene_copy(w, t, set_field(("camera", "fx"), 1e308))), "--out", out_path(t, "s.csv")],
     "camera.fx"),
    ("render", "envmap scale 1e308 (a render of inf)", lambda w, t: render_argv(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("scale", 1e308)), w.brdf, out_path(t)),
     "photos[1].light.scale"),
    ("extract", "flash photo of 3e38 (a slice infer refuses)", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", rgb_exr(t, value=3e38).read_bytes())), "--out",
        out_path(t, "s.csv")], "photos"),
    ("extract", "--labels, flash photo of 3e38 (empty slices, exit 0)", lambda w, t: [
        "extract", str(scene_with_file(w, t, "flash0.exr", rgb_exr(t, value=3e38).read_bytes())),
        "--labels", str(labels_png(w, t)), "--out", out_path(t)], "photos"),
    ("extract", "intensity_rgb [true, 1, 1] (read as 1)", lambda w, t: ["extract", str(
        scene_copy(w, t, set_field(("photos", 0, "light", "intensity_rgb"), [True, 1, 1]))),
        "--out", out_path(t, "s.csv")], "photos[0].light.intensity_rgb"),
    ("extract", "world_from_camera with true on its diagonal", lambda w, t: ["extract", str(
        scene_copy(w, t, set_field(("camera", "world_from_camera"), [
            [True, 0, 0, 0], [0, True, 0, 0], [0, 0, True, 0], [0, 0, 0, True]]))), "--out",
        out_path(t, "s.csv")], "camera.world_from_camera"),
]
