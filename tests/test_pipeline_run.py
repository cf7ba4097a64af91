"""`flashbrdf run` end to end on a small synthetic sphere (128x128) of a held-out material.

The capture is rendered from the MERL (NBRDF proxy) table of red-specular-plastic, which the
default model was not trained on; the reference photo is the sphere under pisa.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from flashbrdf.cli.main import main
from flashbrdf.pipeline.options import DEFAULT_MODEL
from sample_capture import make_sample_capture

HELD_OUT = "red-specular-plastic"


@pytest.fixture(scope="module")
def sphere_scene(merl_proxy, tmp_path_factory):
    if not DEFAULT_MODEL.is_file():
        pytest.fail(f"the default model {DEFAULT_MODEL} is missing: it is part of the project")
    folder = tmp_path_factory.mktemp("sphere") / "scene"
    make_sample_capture(merl_proxy(HELD_OUT), folder, size=128, spp=256, shape="sphere",
                        envmaps={"ref_pisa": "pisa_latlong_256x128.hdr"})
    return folder


@pytest.fixture(scope="module")
def run_report(sphere_scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "out"
    assert main(["run", str(sphere_scene), "--out", str(out), "--methods",
                 "dsgplvm,chandraker", "--spp", "64"]) == 0
    return out, json.loads((out / "report.json").read_text())


def test_run_writes_the_contract_outputs(run_report):
    out, report = run_report
    for name in ("report.md", "slice.csv", "slice.json", "dsgplvm/brdf.binary",
                 "dsgplvm/ref_pisa.exr", "dsgplvm/ref_pisa_compare.json"):
        assert (out / name).is_file(), name
    # one render of each photo for every method, then each method's compare
    assert {"extract", "infer dsgplvm", "render", "compare dsgplvm",
            "compare chandraker"} <= set(report["stages"])
    rows = {(r["photo"], r["method"]): r for r in report["references"]}
    assert set(rows) == {("ref_pisa", "dsgplvm"), ("ref_pisa", "chandraker")}
    compare = json.loads((out / "dsgplvm" / "ref_pisa_compare.json").read_text())
    assert rows["ref_pisa", "dsgplvm"]["delta_e_log_mean"] == pytest.approx(
        compare["delta_e_log_mean"])
    # The sphere (r = 0.1 m, 1 m away, fx = 2.2 * 128 px) covers a disc of radius
    # fx * r / sqrt(d^2 - r^2) = 28.3 px: pi * 28.3^2 = 2516 pixels, less the silhouette's edge.
    assert 2300 < compare["pixels"] < 2600


def test_the_report_rows_hold_files_not_images_and_leave_no_scratch(sphere_scene, tmp_path,
                                                                     monkeypatch):
    """Each (photo, method) row held its render, float64 ΔE map and two masks until the report
    (0.5 GB per row at 24 MP: a 4-reference, 2-method run passed 8 GB): they are files now, the
    render its EXR and the rest, the photo too (once per photo), in OUT/.report_scratch/, read
    photo by photo and removed once the report is written."""
    import numpy as np
    import flashbrdf.pipeline.run as run_module
    seen, real = [], run_module.write_report

    def recording(out, **kw):
        seen.extend(kw["references"])
        return real(out, **kw)
    monkeypatch.setattr(run_module, "write_report", recording)
    out = tmp_path / "out"
    assert main(["run", str(sphere_scene), "--out", str(out), "--methods", "chandraker,noll",
                 "--spp", "4"]) == 0
    assert len(seen) == 2
    for row in seen:
        held = {k for k, v in row.items() if isinstance(v, np.ndarray) and v.size > 1000}
        assert held == set(), held
    assert seen[0]["reference"] == seen[1]["reference"]  # one file for the photo
    assert not (out / ".report_scratch").exists()
    assert (out / "report.html").is_file() and (out / "figures" / "ref_ref_pisa.png").is_file()


def test_run_builds_the_meshs_ray_structure_once(sphere_scene, tmp_path, monkeypatch):
    """Extraction and rendering each loaded the mesh and built its Embree structure (18 s twice
    at 2.9 M faces): the render reuses extraction's."""
    from flashbrdf import capture
    built, real = [], capture.scene_intersector
    monkeypatch.setattr(capture, "scene_intersector", lambda s: built.append(1) or real(s))
    assert main(["run", str(sphere_scene), "--out", str(tmp_path / "out"), "--methods",
                 "chandraker", "--spp", "4"]) == 0
    assert len(built) == 1


def test_predicted_render_matches_the_reference(run_report, sphere_scene):
    """The prediction's render is within a stated Delta E (log-CIELAB, Table 2's metric).

    Measured (2026-11-22): dsgplvm 1.40, chandraker 3.50 (the reference is 256 spp, the renders
    64 spp). The bound 5.0 leaves room for Monte Carlo noise, and is well under what a uniform
    2x brightness error gives on this image (checked below), so a wrong prediction fails. The
    slice of this 128² sphere misses θh bins 0-6 (the highlight is under a pixel): dsgplvm's own
    bound of 2.5 fails a model that mishandles those missing bins (it was at 180 before the
    back-projection imputed them, with the log-RGB model).
    """
    from flashbrdf.brdf.metrics import delta_e_log
    from flashbrdf.render import read_image
    out, report = run_report
    rows = {r["method"]: r for r in report["references"]}
    assert rows["dsgplvm"]["delta_e_log_mean"] < 2.5
    assert rows["chandraker"]["delta_e_log_mean"] < DSGPLVM_BOUND
    reference = read_image(sphere_scene / "ref_pisa.exr")
    on_object = reference.max(axis=-1) > 0
    twice_too_bright = delta_e_log(2 * reference[on_object], reference[on_object]).mean()
    assert twice_too_bright > 2 * DSGPLVM_BOUND


DSGPLVM_BOUND = 5.0


def test_unknown_method_or_missing_model_exit_2_and_write_nothing(sphere_scene, tmp_path,
                                                                   capsys):
    out = tmp_path / "out"
    assert main(["run", str(sphere_scene), "--out", str(out), "--methods", "dsgplvm,magic"]) == 2
    assert "magic" in capsys.readouterr().err and not out.exists()
    assert main(["run", str(sphere_scene), "--out", str(out), "--model",
                 str(tmp_path / "none.npz")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "none.npz" in err[0] and not out.exists()
    # --spp 0 is an error naming the option, not a silent 64 (checked before any work).
    assert main(["run", str(sphere_scene), "--out", str(out), "--spp", "0"]) == 2
    assert "--spp" in capsys.readouterr().err and not out.exists()


def test_a_scene_without_references_compares_nothing_and_renders_previews(sphere_scene,
                                                                           tmp_path, capsys):
    scene = tmp_path / "scene"
    scene.mkdir()
    doc = json.loads((sphere_scene / "scene.json").read_text())
    for name in ("object.ply", "flash.exr", "ambient.exr"):
        (scene / name).symlink_to(sphere_scene / name)
    doc["photos"] = [p for p in doc["photos"] if p["role"] != "reference"]
    (scene / "scene.json").write_text(json.dumps(doc))
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out), "--methods", "chandraker"]) == 0
    # stdout names the page to open, and it is there
    page = capsys.readouterr().out.strip().splitlines()[-1].split()[1]
    assert page == str((out / "report.html").resolve()) and Path(page).is_file()
    report = json.loads((out / "report.json").read_text())
    assert report["references"] == [] and not {"render", "compare chandraker"} & set(
        report["stages"])
    assert any("no reference photo" in note for note in report["notes"])
    # only the previews under the studio map (tests/test_run_previews.py), no reference render
    assert sorted(p.name for p in (out / "chandraker").glob("*.exr")) == [
        "preview_object.exr", "preview_sphere.exr"]


def test_run_export_puts_the_export_and_the_principled_render_beside_the_report(sphere_scene,
                                                                                 tmp_path):
    out = tmp_path / "out"
    assert main(["run", str(sphere_scene), "--out", str(out), "--methods", "chandraker",
                 "--spp", "16", "--export"]) == 0
    assert sorted(p.name for p in (out / "export").iterdir()) == sorted(
        [".flashbrdf-output", "mitsuba_tabulated.xml", "mitsuba_principled.xml", "principled.json",
         "material.gltf"])
    fit = json.loads((out / "export" / "principled.json").read_text())["fit"]
    report = json.loads((out / "report.json").read_text())
    rows = {(r["photo"], r["method"]): r for r in report["references"]}
    assert set(rows) == {("ref_pisa", "chandraker"), ("ref_pisa", "chandraker-principled")}
    assert (out / "chandraker-principled" / "ref_pisa.exr").is_file()
    # The fit's render against the photo: no worse than the tabulated BRDF's by more than the
    # fit's own sphere error under the same map (Delta E adds at most that, plus noise at 16 spp).
    tab, prin = rows["ref_pisa", "chandraker"], rows["ref_pisa", "chandraker-principled"]
    assert prin["delta_e_log_mean"] < tab["delta_e_log_mean"] + fit["render_delta_e_log"] + 1.0
    assert "chandraker-principled" in (out / "report.md").read_text()
    # The export names the table where it is once `run` is done, not in run's temporary folder
    # (the contract's `filename`: a MERL .binary).
    table = str((out / "chandraker" / "brdf.binary").absolute())
    assert f'<string name="filename" value="{table}"/>' in (
        out / "export" / "mitsuba_tabulated.xml").read_text()
    assert json.loads((out / "export" / "principled.json").read_text())["table"] == table
    # every run's table is brdf.binary: its glTF material was named "brdf" in every capture
    gltf = json.loads((out / "export" / "material.gltf").read_text())
    assert [m["name"] for m in gltf["materials"]] == ["out_chandraker"]


def test_run_reports_a_reference_exposure_error_as_its_level(sphere_scene, tmp_path):
    """The same scene with the reference photo 10% too bright: run's report reads the level
    (median reference / render) 1.10x the unchanged scene's, per channel. The renders are the
    same (same slice, method and seed), and a median scales with its values, so the ratio is
    exact up to float32 rounding of the photo (1e-6)."""
    import shutil
    from flashbrdf.render import read_image, write_exr
    scaled = tmp_path / "scaled"
    shutil.copytree(sphere_scene, scaled)
    write_exr(scaled / "ref_pisa.exr", 1.1 * read_image(sphere_scene / "ref_pisa.exr"))
    levels = []
    for scene, out in ((sphere_scene, tmp_path / "a"), (scaled, tmp_path / "b")):
        assert main(["run", str(scene), "--out", str(out), "--methods", "chandraker",
                     "--spp", "16"]) == 0
        report = json.loads((out / "report.json").read_text())
        levels.append(np.array(report["summary"]["chandraker"]["level_ratio_rgb"]))
        assert "reference / render (R, G, B)" in (out / "report.md").read_text()
    assert np.allclose(levels[1] / levels[0], 1.1, rtol=1e-5)
