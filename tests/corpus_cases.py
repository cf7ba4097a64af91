"""The bad-input corpus's cases for the single-material commands: (command, case id, argv
builder (world, tmp) -> list, what the error line names)."""


import numpy as np
import scipy.io
from corpus_inputs import (
    HERE,
    TABLES,
    ascii_ply_cut,
    diligent_copy,
    empty,
    exr_channels,
    flipped_byte,
    image_bytes,
    link,
    marked_folder,
    merl_body,
    merl_copy,
    merl_header,
    model_with_valid_3d,
    nan_slice,
    nan_table,
    normal_map_scene,
    npz_of_other_format,
    npz_of_wrong_shapes,
    out_path,
    ply_triangle,
    png8,
    png_bomb,
    render_argv,
    run_argv,
    same_file_bracketed,
    scene_copy,
    scene_with_envmap,
    scene_with_file,
    scene_with_flash,
    scene_with_literal,
    second_reference,
    set_field,
    slice_n,
    small_exr,
    truncated,
    two_of_one_stem,
    user_folder,
    window_bomb,
    write,
    zip_without_npz,
)

CASES = [
    # merl-slice
    ("merl-slice", "missing table", lambda w, t: ["merl-slice", str(t / "no.binary"), "--out",
                                                  out_path(t, "s.csv")], "no.binary"),
    ("merl-slice", "truncated table", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", truncated(w.brdf))), "--out", out_path(t, "s.csv")], "m.binary"),
    ("merl-slice", "wrong header", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", merl_header(w, [90, 90, 90]))), "--out", out_path(t, "s.csv")], "m.binary"),
    ("merl-slice", "NaN in the table", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", nan_table(w))), "--out", out_path(t, "s.csv")], "m.binary"),
    ("merl-slice", "every value negative (no data)", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", merl_body(w, lambda body: -np.ones_like(body)))), "--out",
        out_path(t, "s.csv")], "m.binary"),
    ("merl-slice", "one channel with no data throughout", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", merl_body(w, lambda body: np.concatenate([
            body[:len(body) // 3], -np.ones(len(body) // 3), body[2 * len(body) // 3:]])))),
        "--out", out_path(t, "s.csv")], "m.binary"),
    ("merl-slice", "values of 1e300", lambda w, t: ["merl-slice", str(write(
        t, "m.binary", merl_body(w, lambda body: body * 1e300))), "--out", out_path(t, "s.csv")],
     "m.binary"),
    ("export", "values of 1e300 (the fit's render check overflowed)", lambda w, t: [
        "export", str(write(t, "m.binary", merl_body(w, lambda body: body * 1e300))), "--out",
        out_path(t)], "m.binary"),
    ("merl-slice", "out is the table", lambda w, t: ["merl-slice", str(w.brdf), "--out",
                                                     str(w.brdf)], TABLES[0]),
    ("merl-slice", "out is a link to the table", lambda w, t: [
        "merl-slice", str(w.brdf), "--out", str(link(t / "s.csv", w.brdf))], "s.csv"),
    ("merl-slice", "out is a folder", lambda w, t: ["merl-slice", str(w.brdf), "--out", str(t)],
     HERE),
    ("merl-slice", "out under a file", lambda w, t: [
        "merl-slice", str(w.brdf), "--out", str(write(t, "f.txt", "x") / "s.csv")], "f.txt"),
    ("merl-slice", "out ends in a slash", lambda w, t: ["merl-slice", str(w.brdf), "--out",
                                                    str(t / "s.csv") + "/"], "s.csv/"),
    ("merl-slice", "table is a folder", lambda w, t: ["merl-slice", str(t), "--out",
                                                      out_path(t, "s.csv")], HERE),
    # extract
    ("extract", "no scene folder", lambda w, t: ["extract", str(t / "none"), "--out",
                                                 out_path(t, "s.csv")], "none"),
    ("extract", "scene.json not JSON", lambda w, t: ["extract", str(scene_with_file(
        w, t, "scene.json", b"{camera: oops")), "--out", out_path(t, "s.csv")], "scene.json"),
    ("extract", "ambient photo is the flash photo", lambda w, t: [  # flash - ambient = 0
        "extract", str(scene_copy(w, t, lambda doc: doc["photos"].append(
            {"file": "flash0.exr", "role": "ambient"}))), "--out", out_path(t, "s.csv")],
     "flash0.exr"),
    *[(command, "no flash photo, only an ambient one (an IndexError traceback)",
       lambda w, t, command=command, extra=extra, name=name: [command, str(scene_copy(
           w, t, lambda doc: doc.__setitem__("photos", [{**doc["photos"][0], "role": "ambient"}]
                                             ))), *extra, "--out", out_path(t, name)],
       "scene.json: photos")
      for command, extra, name in (("extract", [], "s.csv"), ("segment", [], "l.png"),
                                   ("run", ["--methods", "pca"], "run"))],
    ("extract", "camera.width NaN", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("camera", "width"), float("nan")))), "--out", out_path(t, "s.csv")],
     "scene.json: camera.width"),
    ("extract", "camera.height Infinity", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("camera", "height"), float("inf")))), "--out", out_path(t, "s.csv")],
     "scene.json: camera.height"),
    ("extract", "camera.width huge", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("camera", "width"), 10 ** 12))), "--out", out_path(t, "s.csv")],
     "scene.json: camera.width"),
    ("extract", "light position -Infinity", lambda w, t: ["extract", str(scene_copy(
        w, t, lambda d: d["photos"][0]["light"]["position"].__setitem__(1, float("-inf")))),
        "--out", out_path(t, "s.csv")], "photos[0].light.position[1]"),
    ("extract", "NaN in an unknown field", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("provenance",), {"x": [1, float("nan")]}))), "--out", out_path(t, "s.csv")],
     "provenance.x[1]"),
    ("extract", "camera.fx an integer of 400 digits", lambda w, t: ["extract", str(
        scene_with_literal(w, t, ("camera", "fx"), "1" + "0" * 400)), "--out", out_path(t, "s.csv")],
     "scene.json: camera.fx"),
    ("extract", "light position an integer of 400 digits", lambda w, t: ["extract", str(
        scene_with_literal(w, t, ("photos", 0, "light", "position", 0), "-1" + "0" * 400)),
        "--out", out_path(t, "s.csv")], "photos[0].light.position[0]"),
    ("extract", "an integer of 5000 digits (over Python's limit)", lambda w, t: [
        "extract", str(scene_with_literal(w, t, ("camera", "width"), "4" * 5000)), "--out",
        out_path(t, "s.csv")], "scene.json"),
    ("extract", "flash photo's name a lone surrogate (valid JSON, no file name)", lambda w, t: [
        "extract", str(scene_with_literal(w, t, ("photos", 0, "file"), r'"\ud800.exr"')),
        "--out", out_path(t, "s.csv")], "photos[0].file"),
    ("extract", "camera pose not a rotation", lambda w, t: ["extract", str(scene_copy(
        w, t, set_field(("camera", "world_from_camera"), (2 * np.eye(4)).tolist()))), "--out",
        out_path(t, "s.csv")], "camera.world_from_camera"),
    ("extract", "flash photo missing", lambda w, t: ["extract", str(scene_copy(
        w, t, lambda d: d["photos"][0].__setitem__("file", "gone.exr"))), "--out",
        out_path(t, "s.csv")], "gone.exr"),
    ("extract", "flash photo truncated", lambda w, t: ["extract", str(scene_with_file(
        w, t, "flash0.exr", truncated(w.scene / "flash0.exr"))), "--out", out_path(t, "s.csv")],
     "flash0.exr"),
    ("extract", "flash EXR of an alpha channel only", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", exr_channels(t, ("A",)))), "--out",
        out_path(t, "s.csv")], "flash0.exr"),
    ("extract", "flash EXR of X, Y, Z channels", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", exr_channels(t, ("X", "Y", "Z")))), "--out",
        out_path(t, "s.csv")], "flash0.exr"),
    ("extract", "flash EXR of R and G only", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", exr_channels(t, ("R", "G")))), "--out",
        out_path(t, "s.csv")], "flash0.exr"),
    ("extract", "flash photo an 8-bit PNG named .exr", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", image_bytes(".png", np.full((40, 40, 3), 90,
                                                                         np.uint8)))),
        "--out", out_path(t, "s.csv")], "flash0.exr"),
    ("extract", "flash photo a BMP", lambda w, t: ["extract", str(scene_with_flash(
        w, t, "f.bmp", image_bytes(".bmp", np.full((40, 40, 3), 90, np.uint8)))), "--out",
        out_path(t, "s.csv")], "f.bmp"),
    ("extract", "encoding srgb on a float EXR", lambda w, t: ["extract", str(scene_copy(
        w, t, lambda d: d["photos"][0].__setitem__("encoding", "srgb"))), "--out",
        out_path(t, "s.csv")], "flash0.exr"),
    ("extract", "a key given twice in scene.json", lambda w, t: ["extract", str(
        scene_with_literal(w, t, ("camera", "fx"), '100.0, "fx": 5000.0')), "--out",
        out_path(t, "s.csv")], "'fx' is given twice"),
    ("extract", "one file twice in brackets", lambda w, t: ["extract", str(scene_copy(
        w, t, same_file_bracketed)), "--out", out_path(t, "s.csv")], "photos[0].brackets[1].file"),
    ("extract", "ASCII PLY holding half its declared faces", lambda w, t: ["extract", str(
        scene_with_file(w, t, "object.ply", ascii_ply_cut(w))), "--out", out_path(t, "s.csv")],
     "object.ply"),
    ("extract", "flash photo's display window 60000x60000", lambda w, t: ["extract", str(
        scene_with_file(w, t, "flash0.exr", window_bomb(t).read_bytes())), "--out",
        out_path(t, "s.csv")], "flash0.exr"),
    ("extract", "flash photo a PNG of 40000x40000", lambda w, t: ["extract", str(
        scene_with_flash(w, t, "big.png", png_bomb(), encoding="linear")), "--out",
        out_path(t, "s.csv")], "big.png"),
    ("extract", "normal map's mask a PNG of 40000x40000", lambda w, t: [
        "extract", str(write(normal_map_scene(w, t, lambda f: np.save(f, np.ones((40, 40, 3)))),
                             "m.png", png_bomb()).parent), "--out", out_path(t, "s.csv")], "m.png"),
    ("extract", "mesh is garbage", lambda w, t: ["extract", str(scene_with_file(
        w, t, "object.ply", b"ply\nformat nonsense\n")), "--out", out_path(t, "s.csv")],
     "object.ply"),
    ("extract", "mesh face past the last vertex", lambda w, t: ["extract", str(scene_with_file(
        w, t, "object.ply", ply_triangle("0 1 99"))), "--out", out_path(t, "s.csv")], "object.ply"),
    ("extract", "mesh face of a negative vertex", lambda w, t: ["extract", str(scene_with_file(
        w, t, "object.ply", ply_triangle("0 1 -7"))), "--out", out_path(t, "s.csv")], "object.ply"),
    ("extract", "normal map of strings", lambda w, t: ["extract", str(normal_map_scene(
        w, t, lambda f: np.save(f, np.full((40, 40, 3), "a")))), "--out", out_path(t, "s.csv")],
     "n.npy"),
    ("extract", "normal map complex", lambda w, t: ["extract", str(normal_map_scene(
        w, t, lambda f: np.save(f, np.ones((40, 40, 3), complex)))), "--out", out_path(t, "s.csv")],
     "n.npy"),
    ("extract", "normal map an .npz", lambda w, t: ["extract", str(normal_map_scene(
        w, t, lambda f: (np.savez(f.with_suffix(".npz"), n=np.ones((40, 40, 3))),
                         f.with_suffix(".npz").rename(f)))), "--out", out_path(t, "s.csv")], "n.npy"),
    ("extract", "out is scene.json", lambda w, t: ["extract", str(w.scene), "--out",
                                                   str(w.scene / "scene.json")], "scene.json"),
    ("extract", "out is the flash photo", lambda w, t: ["extract", str(w.scene), "--out",
                                                        str(w.scene / "flash0.exr")], "flash0"),
    ("extract", "sidecar would replace scene.json", lambda w, t: [
        "extract", str(w.scene), "--out", str(w.scene / "scene.csv")], "scene"),
    ("extract", "out is a folder", lambda w, t: ["extract", str(w.scene), "--out", str(t)],
     HERE),
    ("extract", "out is the scene folder", lambda w, t: ["extract", str(w.scene), "--out",
                                                         str(w.scene)], "scene"),
    ("extract", "out ends in a slash", lambda w, t: ["extract", str(w.scene), "--out",
                                                 str(t / "s.csv") + "/"], "s.csv/"),
    ("extract", "out empty", lambda w, t: ["extract", str(w.scene), "--out", ""], "--out"),
    ("extract", "max-theta-d 0", lambda w, t: ["extract", str(w.scene), "--out", out_path(t, "s.csv"),
                                               "--max-theta-d", "0"], "--max-theta-d"),
    # infer
    ("infer", "model missing", lambda w, t: ["infer", "--model", str(t / "none.npz"), "--slice",
                                             str(w.slice), "--out", out_path(t, "b.binary")],
     "none.npz"),
    ("infer", "model is a folder", lambda w, t: ["infer", "--model", str(empty(t)), "--slice",
                                                 str(w.slice), "--out", out_path(t, "b.binary")],
     "is a folder, not a model file"),
    ("infer", "model truncated", lambda w, t: ["infer", "--model", str(write(
        t, "m.npz", truncated(w.model, 0.7))), "--slice", str(w.slice), "--out",
        out_path(t, "b.binary")], "m.npz"),
    ("infer", "model empty", lambda w, t: ["infer", "--model", str(write(t, "m.npz", b"")),
                                           "--slice", str(w.slice), "--out", out_path(t, "b.binary")],
     "m.npz"),
    ("infer", "model is text", lambda w, t: ["infer", "--model", str(write(
        t, "m.npz", "a model, honest\n")), "--slice", str(w.slice), "--out", out_path(t, "b.binary")],
     "m.npz"),
    ("infer", "model is another zip", lambda w, t: ["infer", "--model", str(zip_without_npz(t)),
                                                    "--slice", str(w.slice), "--out",
                                                    out_path(t, "b.binary")], "model.npz"),
    ("infer", "model of another format", lambda w, t: [
        "infer", "--model", str(npz_of_other_format(t)), "--slice", str(w.slice), "--out",
        out_path(t, "b.binary")], "model.npz"),
    ("infer", "model arrays of the wrong shape", lambda w, t: [
        "infer", "--model", str(npz_of_wrong_shapes(t)), "--method", "pca", "--slice",
        str(w.slice), "--out", out_path(t, "b.binary")], "model.npz"),
    ("infer", "model valid_3d of the wrong shape", lambda w, t: [
        "infer", "--model", str(model_with_valid_3d(w, t, 2)),
        "--method", "pca", "--slice", str(w.slice), "--out", out_path(t, "b.binary")], "model.npz"),
    ("infer", "slice header wrong", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                                  str(write(t, "s.csv", "a,b,c\n")), "--out",
                                                  out_path(t, "b.binary")], "s.csv"),
    ("infer", "slice too short", lambda w, t: ["infer", "--method", "chandraker", "--slice", str(
        write(t, "s.csv", "".join(w.slice.read_text().splitlines(True)[:40]))), "--out",
        out_path(t, "b.binary")], "s.csv"),
    ("infer", "slice holds NaN", lambda w, t: ["infer", "--method", "chandraker", "--slice", str(
        write(t, "s.csv", nan_slice(w))), "--out", out_path(t, "b.binary")], "s.csv"),
    ("infer", "slice value 1e300 (its prediction overflowed the table)", lambda w, t: [
        "infer", "--method", "chandraker", "--slice", str(write(t, "s.csv", nan_slice(w).replace(
            "nan", "1e300"))), "--out", out_path(t, "b.binary")], "s.csv"),
    ("infer", "a flat 1e20 slice pca extrapolates past what a MERL table holds", lambda w, t: [
        "infer", "--model", str(w.model), "--method", "pca", "--slice", str(write(
            t, "s.csv", "theta_h_deg,r,g,b,n\n" + "".join(
                f"{90 * ((i + 0.5) / 90) ** 2},1e20,1e20,1e20,180\n" for i in range(90)))),
        "--out", out_path(t, "b.binary")], "s.csv"),
    ("infer", "a flat 1e17 slice: pca's table fits in 1/sr but not in MERL's stored units",
     lambda w, t: [
        "infer", "--model", str(w.model), "--method", "pca", "--slice", str(write(
            t, "s.csv", "theta_h_deg,r,g,b,n\n" + "".join(
                f"{90 * ((i + 0.5) / 90) ** 2},1e17,1e17,1e17,180\n" for i in range(90)))),
        "--out", out_path(t, "b.binary")], "s.csv"),
    ("infer", "slice n beyond int64", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                                    str(write(t, "s.csv", slice_n(w, "9" * 30))),
                                                    "--out", out_path(t, "b.binary")], "s.csv"),
    ("infer", "slice n negative in an empty bin", lambda w, t: [
        "infer", "--method", "chandraker", "--slice", str(write(t, "s.csv", slice_n(
            w, "-1", empty_bin=True))), "--out", out_path(t, "b.binary")], "s.csv"),
    ("infer", "out is the slice", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                                str(w.slice), "--out", str(w.slice)], "slice.csv"),
    ("infer", "out is the model", lambda w, t: ["infer", "--model", str(w.model), "--slice",
                                                str(w.slice), "--out", str(w.model)], "model.npz"),
    ("infer", "sidecar would replace the slice", lambda w, t: [
        "infer", "--method", "chandraker", "--slice",
        str(write(t, "s.json", w.slice.read_bytes())), "--out", out_path(t, "s.binary")], "s.json"),
    ("infer", "out ends in a slash", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                               str(w.slice), "--out", str(t / "b.binary") + "/"],
     "b.binary/"),
    ("infer", "out empty", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                         str(w.slice), "--out", ""], "--out"),
    ("infer", "slice empty (it named no file)", lambda w, t: [
        "infer", "--method", "chandraker", "--slice", "", "--out", out_path(t, "b.binary")],
     "--slice"),
    ("infer", "merl-dir empty (it named no folder)", lambda w, t: [
        "infer", "--model", str(w.model), "--slice", str(w.slice), "--merl-dir", "", "--out",
        out_path(t, "b.binary")], "--merl-dir"),
    ("infer", "out is a folder", lambda w, t: ["infer", "--method", "chandraker", "--slice",
                                               str(w.slice), "--out", str(t)], HERE),
    # train
    ("train", "merl-dir missing", lambda w, t: ["train", "--merl-dir", str(t / "none"), "--out",
                                                out_path(t, "m.npz")], "none"),
    ("train", "merl-dir empty", lambda w, t: ["train", "--merl-dir", str(empty(t)), "--out",
                                              out_path(t, "m.npz")], "empty"),
    ("train", "merl-dir is a file", lambda w, t: ["train", "--merl-dir", str(w.slice), "--out",
                                                  out_path(t, "m.npz")], "slice.csv"),
    ("train", "a truncated table", lambda w, t: ["train", "--merl-dir", str(merl_copy(
        w, t, truncated(w.brdf, 0.1))), "--out", out_path(t, "m.npz")], "bad.binary"),
    ("train", "a table of no data in a second folder", lambda w, t: [
        "train", "--merl-dir", str(w.merl_dir), "--merl-dir", str(write(
            empty(t), "none.binary", merl_body(w, lambda body: -np.ones_like(body))).parent),
        "--out", out_path(t, "m.npz")], "none.binary"),
    ("train", "out is a table", lambda w, t: ["train", "--merl-dir", str(w.merl_dir), "--out",
                                              str(w.merl_dir / f"{TABLES[1]}.binary")], TABLES[1]),
    ("train", "out is the merl-dir", lambda w, t: ["train", "--merl-dir", str(w.merl_dir),
                                                   "--out", str(w.merl_dir)], "merl"),
    ("train", "out is a folder", lambda w, t: ["train", "--merl-dir", str(w.merl_dir), "--out",
                                               str(t)], HERE),
    # render
    ("render", "brdf missing", lambda w, t: render_argv(w.scene, t / "none.binary", out_path(t)),
     "none.binary"),
    ("render", "brdf truncated", lambda w, t: render_argv(
        w.scene, write(t, "b.binary", truncated(w.brdf)), out_path(t)), "b.binary"),
    ("render", "out is the scene", lambda w, t: render_argv(w.scene, w.brdf, w.scene), "scene"),
    ("render", "out holds the scene", lambda w, t: render_argv(w.scene, w.brdf, w.base), "corpus"),
    ("render", "out is a file", lambda w, t: render_argv(w.scene, w.brdf, write(t, "f.txt", "x")),
     "f.txt"),
    ("render", "out is someone's folder", lambda w, t: render_argv(w.scene, w.brdf, user_folder(t)),
     "mine"),
    ("render", "force on someone's folder", lambda w, t: render_argv(
        w.scene, w.brdf, user_folder(t), "--force"), "mine"),
    ("render", "earlier output without --force", lambda w, t: render_argv(
        w.scene, w.brdf, marked_folder(t)), "old"),
    ("render", "envmap missing", lambda w, t: render_argv(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("file", "gone.hdr")), w.brdf,
        out_path(t)), "gone.hdr"),
    ("render", "envmap garbage", lambda w, t: render_argv(scene_with_file(
        w, t, "env.hdr", b"#?RADIANCE\nnonsense"), w.brdf, out_path(t)), "env.hdr"),
    ("render", "envmap's display window 60000x60000", lambda w, t: render_argv(scene_with_file(
        w, t, "env.hdr", window_bomb(t).read_bytes()), w.brdf, out_path(t)), "env.hdr"),
    ("render", "world_from_envmap zero", lambda w, t: render_argv(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("world_from_envmap",
                                                            np.zeros((3, 3)).tolist())),
        w.brdf, out_path(t)), "photos[1].light.world_from_envmap"),
    ("render", "world_from_envmap 3I", lambda w, t: render_argv(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("world_from_envmap",
                                                            (3 * np.eye(3)).tolist())),
        w.brdf, out_path(t)), "photos[1].light.world_from_envmap"),
    ("render", "world_from_envmap a mirror", lambda w, t: render_argv(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__(
            "world_from_envmap", np.diag([1.0, 1.0, -1.0]).tolist())),
        w.brdf, out_path(t)), "photos[1].light.world_from_envmap"),
    ("render", "reference photo wrong size", lambda w, t: render_argv(scene_with_file(
        w, t, "ref_env.exr", small_exr(t).read_bytes()), w.brdf, out_path(t)), "ref_env.exr"),
    ("render", "camera cx 1e35 (no pixel sees the object)", lambda w, t: render_argv(scene_copy(
        w, t, lambda d: d["camera"].__setitem__("cx", 1e35)), w.brdf, out_path(t)), "camera"),
    ("render", "a reference photo's own camera looks away", lambda w, t: render_argv(scene_copy(
        w, t, lambda d: d["photos"][1].__setitem__("camera", d["camera"] | {
            "world_from_camera": (np.diag([1.0, -1.0, -1.0, 1.0])
                                  @ np.asarray(d["camera"]["world_from_camera"])).tolist()})),
        w.brdf, out_path(t)), "photos[1].camera"),
    ("render", "envmap of negative radiance", lambda w, t: render_argv(scene_with_envmap(
        w, t, "neg.exr", exr_channels(t, ("R", "G", "B"), values=-1.0, width=32, height=16)), w.brdf, out_path(t)),
     "neg.exr"),
    ("render", "spp 0", lambda w, t: render_argv(w.scene, w.brdf, out_path(t), "--spp", "0"), "--spp"),
    ("render", "spp 10**11 (out of memory)", lambda w, t: render_argv(
        w.scene, w.brdf, out_path(t), "--spp", str(10 ** 11)), "--spp"),
    # compare
    ("compare", "pred missing", lambda w, t: ["compare", str(t / "none.exr"), str(w.ref),
                                              "--out", out_path(t)], "none.exr"),
    ("compare", "ref garbage", lambda w, t: ["compare", str(w.pred), str(write(
        t, "r.exr", b"\x76\x2f\x31\x01garbage")), "--out", out_path(t)], "r.exr"),
    ("compare", "sizes differ", lambda w, t: ["compare", str(w.pred), str(small_exr(t)),
                                              "--out", out_path(t)], "small.exr"),
    ("compare", "pred's display window 60000x60000", lambda w, t: [
        "compare", str(window_bomb(t, "p.exr")), str(w.ref), "--out", out_path(t)], "p.exr"),
    ("compare", "mask wrong size", lambda w, t: ["compare", str(w.pred), str(w.ref), "--mask",
                                                 str(small_exr(t, "m.exr")), "--out", out_path(t)],
     "m.exr"),
    ("compare", "mask garbage", lambda w, t: ["compare", str(w.pred), str(w.ref), "--mask",
                                              str(write(t, "m.png", b"\x89PNG\r\n\x1a\nxx")),
                                              "--out", out_path(t)], "m.png"),
    ("compare", "out is pred", lambda w, t: ["compare", str(w.pred), str(w.ref), "--out",
                                             str(w.pred)], "pred.exr"),
    ("compare", "out holds pred", lambda w, t: ["compare", str(w.pred), str(w.ref), "--out",
                                                str(w.base)], "corpus"),
    ("compare", "out is a file", lambda w, t: ["compare", str(w.pred), str(w.ref), "--out",
                                               str(write(t, "f.txt", "x"))], "f.txt"),
    # run
    ("run", "model truncated", lambda w, t: run_argv(w.scene, out_path(t), "--model", str(write(
        t, "m.npz", truncated(w.model, 0.7)))), "m.npz"),
    ("run", "model is text", lambda w, t: run_argv(w.scene, out_path(t), "--model", str(write(
        t, "m.npz", "not a model\n"))), "m.npz"),
    ("run", "model damaged inside", lambda w, t: run_argv(w.scene, out_path(t), "--model", str(write(
        t, "m.npz", flipped_byte(w.model)))), "m.npz"),
    ("run", "model of another format", lambda w, t: run_argv(w.scene, out_path(t), "--model",
                                                         str(npz_of_other_format(t))),
     "model.npz"),
    ("run", "model missing", lambda w, t: run_argv(w.scene, out_path(t), "--model", str(t / "n.npz")),
     "n.npz"),
    ("run", "envmap missing", lambda w, t: run_argv(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("file", "gone.hdr")), out_path(t)),
     "gone.hdr"),
    ("run", "envmap not lat-long", lambda w, t: run_argv(scene_with_file(
        w, t, "env.hdr", small_exr(t, "e.exr").read_bytes()), out_path(t)), "env.hdr"),
    ("run", "reference photo wrong size", lambda w, t: run_argv(scene_with_file(
        w, t, "ref_env.exr", small_exr(t).read_bytes()), out_path(t)), "ref_env.exr"),
    ("run", "flash photo truncated", lambda w, t: run_argv(scene_with_file(
        w, t, "flash0.exr", truncated(w.scene / "flash0.exr")), out_path(t)), "flash0.exr"),
    ("run", "scale NaN", lambda w, t: run_argv(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("scale", float("nan"))), out_path(t)),
     "photos[1].light.scale"),
    ("run", "world_from_envmap 3I", lambda w, t: run_argv(scene_copy(
        w, t, lambda d: d["photos"][1]["light"].__setitem__("world_from_envmap",
                                                            (3 * np.eye(3)).tolist())), out_path(t)),
     "world_from_envmap"),
    ("run", "out is the scene", lambda w, t: run_argv(w.scene, w.scene), "scene"),
    ("run", "out holds the model", lambda w, t: run_argv(w.scene, w.base), "corpus"),
    ("run", "out is the model", lambda w, t: run_argv(w.scene, w.model, "--model", str(w.model)),
     "model.npz"),
    ("run", "out is a file", lambda w, t: run_argv(w.scene, write(t, "f.txt", "x")), "f.txt"),
    ("run", "out is someone's folder", lambda w, t: run_argv(w.scene, user_folder(t), "--force"),
     "mine"),
    ("run", "earlier output without --force", lambda w, t: run_argv(w.scene, marked_folder(t)),
     "old"),
    ("run", "out under a file", lambda w, t: run_argv(w.scene, write(t, "f.txt", "x") / "out"),
     "f.txt"),
    ("run", "out empty", lambda w, t: run_argv(w.scene, ""), "--out"),
    ("run", "unknown method", lambda w, t: ["run", str(w.scene), "--out", out_path(t), "--methods",
                                            "magic"], "--methods"),
    # evaluate
    ("evaluate", "merl-dir missing", lambda w, t: ["evaluate", "--merl-dir", str(t / "none"),
                                                   "--out", out_path(t)], "none"),
    ("evaluate", "merl-dir empty", lambda w, t: ["evaluate", "--merl-dir", str(empty(t)),
                                                 "--out", out_path(t)], "empty"),
    ("evaluate", "out is the merl-dir", lambda w, t: ["evaluate", "--merl-dir", str(w.merl_dir),
                                                      "--out", str(w.merl_dir)], "merl"),
    ("evaluate", "out holds the merl-dir", lambda w, t: ["evaluate", "--merl-dir",
                                                         str(w.merl_dir), "--out", str(w.base)],
     "corpus"),
    ("evaluate", "out is a file", lambda w, t: ["evaluate", "--merl-dir", str(w.merl_dir),
                                                "--out", str(write(t, "f.txt", "x"))], "f.txt"),
    ("evaluate", "out is someone's folder", lambda w, t: [
        "evaluate", "--merl-dir", str(w.merl_dir), "--out", str(user_folder(t))], "mine"),
    # import-diligent
    ("import-diligent", "folder missing", lambda w, t: [
        "import-diligent", str(t / "none"), "--flash", "1", "--out", out_path(t)], "none"),
    ("import-diligent", "intensities missing", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_intensities.txt")
                                             .unlink())), "--flash", "1", "--out", out_path(t)],
     "light_intensities.txt"),
    ("import-diligent", "Normal_gt.mat truncated", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "Normal_gt.mat").write_bytes(
            truncated(f / "Normal_gt.mat")))), "--flash", "1", "--out", out_path(t)], "Normal_gt.mat"),
    ("import-diligent", "photo garbage", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "003.png").write_bytes(
            b"\x89PNG\r\n\x1a\n..."))), "--flash", "1", "--out", out_path(t)], "003.png"),
    ("import-diligent", "light directions NaN", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_directions.txt")
                                             .write_text("nan 0 1\n0 0 1\n0 0 1\n0 0 1\n"))),
        "--flash", "1", "--out", out_path(t)], "light_directions.txt"),
    ("import-diligent", "light intensity 1e-50 (inf and NaN photos in float32)", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_intensities.txt")
                                             .write_text("1e-50 1 1\n" + "1 1 1\n" * 3))),
        "--flash", "1", "--out", out_path(t)], "light_intensities.txt"),
    ("import-diligent", "light intensity 1e308 (black photos in float32)", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_intensities.txt")
                                             .write_text("1 1 1\n" * 3 + "1e308 1 1\n"))),
        "--flash", "1", "--out", out_path(t)], "light_intensities.txt"),
    ("import-diligent", "a photo of 40000x40000", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "003.png").write_bytes(
            png_bomb()))), "--flash", "1", "--out", out_path(t)], "003.png"),
    ("import-diligent", "8-bit among 16-bit", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, png8)), "--flash", "1", "--out", out_path(t)],
     "002.png"),
    ("import-diligent", "out is the folder", lambda w, t: [
        "import-diligent", str(w.diligent), "--flash", "1", "--out", str(w.diligent)], "obj"),
    ("import-diligent", "out holds the folder", lambda w, t: [
        "import-diligent", str(w.diligent), "--flash", "1", "--out", str(w.base)], "corpus"),
    ("import-diligent", "out is a capture folder", lambda w, t: [
        "import-diligent", str(w.diligent), "--flash", "1", "--out", str(scene_copy(w, t))],
     "scene"),
    ("import-diligent", "flash index 0", lambda w, t: [
        "import-diligent", str(w.diligent), "--flash", "0", "--out", out_path(t)], "--flash"),
    ("import-diligent", "light directions empty (numpy warned on a second line)", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "light_directions.txt")
                                             .write_text(""))), "--flash", "1", "--out", out_path(t)],
     "light_directions.txt"),
    ("import-diligent", "Normal_gt a string", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: scipy.io.savemat(
            f / "Normal_gt.mat", {"Normal_gt": "up"}))), "--flash", "1", "--out", out_path(t)],
     "Normal_gt.mat"),
    ("import-diligent", "filenames.txt not UTF-8 (a traceback)", lambda w, t: [
        "import-diligent", str(diligent_copy(w, t, lambda f: (f / "filenames.txt").write_bytes(
            b"\xff\xfe0\x000\x001\x00"))), "--flash", "1", "--out", out_path(t)], "filenames.txt"),
    ("import-diligent", "filenames.txt lists a photo twice (one EXR replaced the other)",
     lambda w, t: ["import-diligent", str(diligent_copy(w, t, lambda f: (
         f / "filenames.txt").write_text("001.png\n002.png\n003.png\n001.png\n"))), "--flash",
        "1", "--out", out_path(t)], "filenames.txt"),
    ("import-diligent", "filenames.txt: a/x.png and b/x.png (both written as x.exr)",
     lambda w, t: ["import-diligent", str(diligent_copy(w, t, two_of_one_stem)), "--flash", "1",
                   "--out", out_path(t)], "filenames.txt"),
    ("render", "two reference photos of one stem (one render replaced the other)", lambda w, t:
     render_argv(scene_copy(w, t, second_reference("ref_env.hdr")), w.brdf, out_path(t)),
     "photos[2].file"),
    ("run", "two reference photos of one stem in two folders", lambda w, t: run_argv(
        scene_copy(w, t, second_reference("sub/ref_env.exr")), out_path(t)), "photos[2].file"),
    ("render", "reference photos ref_env and ref_env_delta_e (both write ref_env_delta_e.png)",
     lambda w, t: render_argv(scene_copy(w, t, second_reference("ref_env_delta_e.exr")), w.brdf,
                          out_path(t)), "photos[2].file"),
]

