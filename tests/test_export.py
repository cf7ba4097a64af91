"""Export: the numpy principled BSDF, the fit recovering known parameters, and `flashbrdf export`."""

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from flashbrdf.brdf.merl import write_merl
from flashbrdf.brdf.metrics import brdf_error
from flashbrdf.brdf.models.microfacet import ggx_d, gtr1_d
from flashbrdf.brdf.models.principled import (clearcoat_alpha, main_lobe_exists,
                                              principled_brdf_angles, principled_brdf_local,
                                              tabulate_principled)
from flashbrdf.brdf.models.principled_fit import fit_principled
from flashbrdf.brdf.views import table_2d
from flashbrdf.cli.main import main
from flashbrdf.render.export import FORMATS, blender_parameters, gltf_material

# The four known materials: rough and glossy dielectrics, a rough metal, a clearcoated paint.
KNOWN = {
    "rough_dielectric": {"base_color": [0.6, 0.3, 0.2], "roughness": 0.7, "specular": 0.5},
    "glossy_dielectric": {"base_color": [0.1, 0.3, 0.6], "roughness": 0.2, "specular": 0.5},
    "rough_metal": {"base_color": [0.9, 0.6, 0.3], "roughness": 0.5, "metallic": 1.0},
    "clearcoat_paint": {"base_color": [0.5, 0.05, 0.05], "roughness": 0.5, "clearcoat": 1.0,
                        "clearcoat_gloss": 0.8},
}


def test_principled_at_normal_incidence_is_burley_diffuse_plus_ggx_peak():
    # wi = wo = n: Schlick weights are 0, so diffuse = (1 - m) base / pi and retro = 0; the GGX
    # peak is D(1) G / 4 = 1 / (pi alpha^2 4) times F; F_dielectric(1, eta) = ((eta-1)/(eta+1))^2.
    base, rough, specular = np.array([0.2, 0.4, 0.6]), 0.5, 0.5
    eta = 2.0 / (1.0 - np.sqrt(0.08 * specular)) - 1.0            # 1.5
    n = np.array([0.0, 0.0, 1.0])
    value = principled_brdf_local(n, n, {"base_color": base, "roughness": rough,
                                         "specular": specular})
    peak = ((eta - 1) / (eta + 1)) ** 2 / (4 * np.pi * rough ** 4)
    np.testing.assert_allclose(value, base / np.pi + peak, rtol=1e-12)


def test_principled_has_no_main_lobe_at_specular_zero_as_in_mitsuba():
    """Mitsuba's principled evaluates its main lobe only where the dielectric Fresnel term is
    positive: at specular 0 (eta = 1) a metal is black (test_mitsuba_bsdf checks it against
    Mitsuba itself), and the port must say so, or a fit landing there reports a material Mitsuba
    does not render. At specular 1e-3 the metal's peak is whole."""
    n = np.array([0.0, 0.0, 1.0])
    metal = {"base_color": [0.9, 0.6, 0.3], "roughness": 0.1, "metallic": 1.0}
    peak = np.array(metal["base_color"]) / (4 * np.pi * 0.1 ** 4)     # F = base at normal, G = 1
    assert np.all(principled_brdf_local(n, n, metal | {"specular": 0.0}) == 0)
    assert not main_lobe_exists(1e-14) and main_lobe_exists(1e-3)
    np.testing.assert_allclose(principled_brdf_local(n, n, metal | {"specular": 1e-3}),
                               peak, rtol=1e-12)


def test_principled_is_zero_below_horizon_and_reciprocal():
    rng = np.random.default_rng(1)
    wi, wo = rng.normal(size=(2, 500, 3))
    wi /= np.linalg.norm(wi, axis=-1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=-1, keepdims=True)
    params = {**KNOWN["clearcoat_paint"], "sheen": 0.5, "sheen_tint": 0.5, "spec_tint": 0.3,
              "metallic": 0.3}
    f = principled_brdf_local(wi, wo, params)
    below = (wi[:, 2] <= 0) | (wo[:, 2] <= 0)
    assert np.all(f[below] == 0) and np.all(f[~below] > 0)
    np.testing.assert_allclose(principled_brdf_local(wo, wi, params), f, rtol=1e-12)
    # grazing and theta_h = 0 stay finite
    assert np.all(np.isfinite(principled_brdf_angles(1e-9, 1e-9, 1.0, 1.0, params)))


@pytest.mark.parametrize("name", list(KNOWN))
def test_fit_recovers_known_parameters(name):
    truth = KNOWN[name]
    table = tabulate_principled(truth)
    result = fit_principled(table, n_bins=3000)
    fit = result["params"]
    assert abs(fit["roughness"] - truth["roughness"]) <= 0.05
    assert abs(fit["metallic"] - truth.get("metallic", 0.0)) <= 0.1
    np.testing.assert_allclose(fit["base_color"], truth["base_color"], rtol=0.05)
    # The true parameters' 2D LAB-log error is 0 by construction (same function, same bins), so
    # 1.5x it is 0: we allow 0.05 LAB-log units, 20x below a just-noticeable Delta E of 1.
    assert brdf_error(table_2d(tabulate_principled(fit)), table_2d(table)) <= 0.05
    # Under 10 s on an idle core (the fit is single-threaded); CPU time, because wall time on a
    # shared CI machine says more about the neighbours. 3-6 s measured; 15 leaves room for a
    # slower CPU.
    assert result["cpu_seconds"] < 15


def _gltf_is_valid(doc):
    """The glTF 2.0 structure a loader needs for a material-only document."""
    assert doc["asset"]["version"] == "2.0"
    (material,) = doc["materials"]
    pbr = material["pbrMetallicRoughness"]
    assert len(pbr["baseColorFactor"]) == 4
    assert all(0 <= v <= 1 for v in pbr["baseColorFactor"])
    assert 0 <= pbr["metallicFactor"] <= 1 and 0 <= pbr["roughnessFactor"] <= 1
    used = set(material.get("extensions", {}))
    assert used == set(doc.get("extensionsUsed", []))
    assert used <= {"KHR_materials_specular", "KHR_materials_ior", "KHR_materials_clearcoat",
                    "KHR_materials_sheen"}
    return material


def test_a_metallic_paint_is_fitted_as_a_metal(merl_proxy):
    """The fit screened its 12 starts by their initial residual and kept 3: the metal starts
    (whose base colour is the diffuse guess) were dropped, and gold-metallic-paint came out a
    near-black dielectric, at 2.1x the loss every start reaches (0.043 against 0.020)."""
    from flashbrdf.brdf.merl import read_merl
    fit = fit_principled(read_merl(merl_proxy("gold-metallic-paint")))
    assert fit["starts"] == 12 and fit["params"]["metallic"] > 0.9
    assert fit["cost"] < 0.025
    base = fit["params"]["base_color"]
    assert base[0] > base[1] > base[2] and base[0] > 0.1     # gold, not black


def test_a_saturated_sheen_keeps_its_hue_in_gltf():
    """Blender and Mitsuba take the sheen tint lerp(1, base / luminance, tint) unclamped ([4.70,
    0.03, 0.03] for a nearly pure red at tint 1); glTF caps the colour at 1, and clipping per
    channel turned [1.8, 0.9, 0.3] into [1, 0.9, 0.3], another hue. Scaled down whole, the
    glTF colour is Blender's up to one factor."""
    params = {"base_color": [0.9, 0.45, 0.15], "roughness": 0.5, "metallic": 0.0,
              "specular": 0.5, "spec_tint": 0.0, "sheen": 1.0, "sheen_tint": 1.0,
              "clearcoat": 0.0, "clearcoat_gloss": 0.0}
    blender = np.array(blender_parameters(params)["Sheen Tint"][:3])
    gltf = np.array(_gltf_is_valid(gltf_material(params))["extensions"]["KHR_materials_sheen"]
                    ["sheenColorFactor"])
    assert blender.max() > 1 and gltf.max() == pytest.approx(1.0)
    np.testing.assert_allclose(gltf / gltf.max(), blender / blender.max(), rtol=1e-12)


@pytest.mark.parametrize("gloss", [0.0, 0.5, 0.8, 1.0])
def test_gltf_and_blender_coat_peaks_as_high_as_mitsubas(gloss):
    """glTF's and Blender's coat is GGX, Mitsuba's GTR1: with GTR1's alpha as GGX's the coat's
    highlight was −ln(a²) / (1 − a²) times too bright (4.6× at gloss 0, 14× at gloss 1). At
    θh = 0 and normal incidence every other factor of the two coats is the same (Fresnel 0.04,
    masking 1; Mitsuba's 0.25 weight is GGX's 1 / (4 cos θi cos θo)), so the distributions'
    peaks must agree."""
    params = {**KNOWN["clearcoat_paint"], "metallic": 0.0, "specular": 0.5, "spec_tint": 0.0,
              "sheen": 0.0, "sheen_tint": 0.0, "clearcoat_gloss": gloss}
    roughness = blender_parameters(params)["Coat Roughness"]
    assert roughness == gltf_material(params)["materials"][0]["extensions"][
        "KHR_materials_clearcoat"]["clearcoatRoughnessFactor"]
    ggx_peak = ggx_d(1.0, roughness ** 2)
    gtr1_peak = gtr1_d(1.0, clearcoat_alpha(gloss))
    assert ggx_peak == pytest.approx(gtr1_peak, rel=1e-9)


def test_gltf_uses_extensions_only_where_the_fit_does():
    plain = _gltf_is_valid(gltf_material(KNOWN["rough_dielectric"] | {"metallic": 0.0,
        "spec_tint": 0.0, "sheen": 0.0, "sheen_tint": 0.0, "clearcoat": 0.0,
        "clearcoat_gloss": 0.0}))
    assert "extensions" not in plain
    coat = _gltf_is_valid(gltf_material(KNOWN["clearcoat_paint"] | {"metallic": 0.0,
        "specular": 0.8, "spec_tint": 0.5, "sheen": 0.0, "sheen_tint": 0.0}))
    ext = coat["extensions"]
    assert ext["KHR_materials_clearcoat"]["clearcoatFactor"] == 1.0
    # gloss 0.8 -> GTR1 alpha a = 0.1 - 0.099 * 0.8 = 0.0208; GGX alpha a sqrt(-ln a² / (1 - a²))
    a = 0.0208
    ggx_alpha = a * np.sqrt(-np.log(a * a) / (1 - a * a))
    assert ext["KHR_materials_clearcoat"]["clearcoatRoughnessFactor"] == pytest.approx(
        ggx_alpha ** 0.5)
    assert ext["KHR_materials_ior"]["ior"] == pytest.approx(2 / (1 - (0.08 * 0.8) ** 0.5) - 1)
    assert "KHR_materials_specular" in ext and "KHR_materials_sheen" not in ext


@pytest.fixture(scope="module")
def paint_table(tmp_path_factory):
    path = tmp_path_factory.mktemp("export") / "paint.binary"
    write_merl(path, tabulate_principled(KNOWN["clearcoat_paint"]))
    return path


def test_export_writes_the_contract_files(paint_table, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["export", str(paint_table), "--out", str(out)]) == 0
    # beside the contract's four files, only the hidden marker of a folder flashbrdf made
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [".flashbrdf-output", "mitsuba_tabulated.xml", "mitsuba_principled.xml", "principled.json",
         "material.gltf"])
    tab = ET.parse(out / "mitsuba_tabulated.xml").getroot()
    assert tab.tag == "bsdf" and tab.get("type") == "flashbrdf_tabulated"
    (filename,) = tab.findall("string")
    assert filename.get("name") == "filename" and filename.get("value") == str(paint_table)
    prin = ET.parse(out / "mitsuba_principled.xml").getroot()
    assert prin.get("type") == "principled"
    doc = json.loads((out / "principled.json").read_text())
    names = {"base_color", "roughness", "metallic", "specular", "spec_tint", "sheen",
             "sheen_tint", "clearcoat", "clearcoat_gloss"}
    assert names <= set(doc)
    assert {e.get("name") for e in prin} == names
    assert doc["roughness"] == pytest.approx(0.5, abs=0.05)
    assert doc["blender"]["Coat Weight"] == pytest.approx(doc["clearcoat"])
    assert doc["fit"]["lab_log_2d"] <= 0.05
    assert doc["fit"]["optimiser"].startswith("scipy.optimize.least_squares")
    if doc["fit"]["render"] is not None:   # pisa from ../shared; same sampler and seed: tiny
        assert doc["fit"]["render_delta_e_log"] < 0.05
    _gltf_is_valid(json.loads((out / "material.gltf").read_text()))
    # A second export into its own previous output is refused without --force, replaces it with
    capsys.readouterr()
    assert main(["export", str(paint_table), "--out", str(out), "--formats", "gltf,mitsuba"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    assert main(["export", str(paint_table), "--out", str(out), "--formats", "gltf,mitsuba",
                 "--force"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [".flashbrdf-output", "mitsuba_tabulated.xml", "mitsuba_principled.xml", "material.gltf"])


@pytest.mark.parametrize("case", ["format", "no_bins", "inside_input", "holds_input"])
def test_export_bad_input_exits_2_with_one_line(paint_table, tmp_path, capsys, case):
    table, out = paint_table, tmp_path / "out"
    args = []
    if case == "format":
        args = ["--formats", "mitsuba,usd"]
    elif case == "no_bins":
        table = tmp_path / "empty.binary"
        write_merl(table, np.full((90, 90, 180, 3), np.nan))
    elif case == "inside_input":
        out = paint_table / "export"
    else:
        out = paint_table.parent
    before = sorted(p.name for p in paint_table.parent.iterdir())
    capsys.readouterr()
    assert main(["export", str(table), "--out", str(out), *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and ("--formats" in err[0] or str(table) in err[0] or str(out) in err[0])
    assert not (tmp_path / "out").exists()
    assert sorted(p.name for p in paint_table.parent.iterdir()) == before


def test_formats_are_the_contracts():
    assert FORMATS == ("mitsuba", "principled", "gltf")


def test_export_reads_an_envmap_only_when_a_flag_names_it(tmp_path):
    """Nothing may depend on files outside the project unless a flag names them: without
    --envmap principled.json's render check is null (it used ../shared's pisa when present); with
    --envmap FILE the check renders under FILE."""
    import OpenImageIO as oiio
    table = tmp_path / "lambert.binary"
    write_merl(table, np.broadcast_to([0.1, 0.2, 0.3], (90, 90, 180, 3)))
    assert main(["export", str(table), "--out", str(tmp_path / "plain"), "--formats",
                 "principled"]) == 0
    doc = json.loads((tmp_path / "plain" / "principled.json").read_text())
    assert doc["fit"]["render"] is None and doc["fit"]["render_delta_e_log"] is None
    sky = str(tmp_path / "sky_latlong.exr")
    out = oiio.ImageOutput.create(sky)
    out.open(sky, oiio.ImageSpec(16, 8, 3, oiio.FLOAT))
    out.write_image(np.ones((8, 16, 3), np.float32))
    out.close()
    assert main(["export", str(table), "--out", str(tmp_path / "lit"), "--formats", "principled",
                 "--envmap", sky]) == 0
    doc = json.loads((tmp_path / "lit" / "principled.json").read_text())
    assert doc["fit"]["render"]["envmap"] == "sky_latlong.exr"
    assert doc["fit"]["render_delta_e_log"] == pytest.approx(0.0, abs=0.5)


def test_export_warns_when_mitsubas_xml_cannot_hold_the_tables_path(paint_table, tmp_path, capsys):
    """Mitsuba's load_file substitutes $name in every attribute, with no escape: a table under
    a folder named 'a$spp' makes mitsuba_tabulated.xml fail to load ("undefined parameter") or
    load another file. The export says so, once, and how to load the table instead."""
    folder = tmp_path / "a$spp"
    folder.mkdir()
    table = folder / "paint.binary"
    table.write_bytes(paint_table.read_bytes())
    assert main(["export", str(table), "--out", str(tmp_path / "dollar"), "--formats",
                 "mitsuba"]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning")]
    assert len(warned) == 1 and "'$'" in warned[0] and "load_dict" in warned[0]
    assert main(["export", str(paint_table), "--out", str(tmp_path / "plain"), "--formats",
                 "mitsuba"]) == 0
    assert not [line for line in capsys.readouterr().err.splitlines()
                if line.startswith("warning")]
