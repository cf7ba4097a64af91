"""The Mitsuba 3 plugin `flashbrdf_tabulated` against our own renderer's reading of the same table.

Skipped without mitsuba (`pip install -e ".[mitsuba]"`); the llvm_ad_rgb tests also need a
usable LLVM (Debian 12: `apt-get install libllvm19`, see render/mitsuba_bsdf.py).
"""

import numpy as np
import pytest

from flashbrdf.brdf.merl import read_merl, write_merl
from flashbrdf.brdf.models.principled import tabulate_principled
from flashbrdf.brdf.models import TabulatedBRDF, sample_cosine

mi = pytest.importorskip("mitsuba", reason="mitsuba is not installed (pip install -e \".[mitsuba]\")")
import flashbrdf.render.mitsuba_bsdf as mbsdf  # noqa: E402  (after the skip)

# A glossy plastic: a diffuse body and a GGX highlight exercise both halves of the sampler.
PLASTIC = {"base_color": [0.5, 0.2, 0.1], "roughness": 0.3, "specular": 0.5}


@pytest.fixture(scope="module")
def plastic(tmp_path_factory):
    path = tmp_path_factory.mktemp("mitsuba") / "plastic.binary"
    write_merl(path, tabulate_principled(PLASTIC))
    return path


def _directions(rng, n):
    v = rng.normal(size=(n, 3))
    v[:, 2] = np.abs(v[:, 2]) + 1e-3
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_scalar_eval_is_our_table_lookup(plastic):
    mbsdf.register("scalar_rgb")
    import drjit as dr
    bsdf = mi.load_dict({"type": "flashbrdf_tabulated", "filename": str(plastic)})
    rng = np.random.default_rng(0)
    wi, wo = _directions(rng, 16), _directions(rng, 16)
    expected = TabulatedBRDF(read_merl(plastic)).evaluate_local(wi, wo) * wo[:, 2:3]
    ctx = mi.BSDFContext()
    for a, b, e in zip(wi, wo, expected):
        si = dr.zeros(mi.SurfaceInteraction3f)
        si.wi = mi.Vector3f(*a)
        # float32 in Mitsuba: a bin index can differ only where a float32 angle crosses a bin edge
        np.testing.assert_allclose(list(bsdf.eval(ctx, si, mi.Vector3f(*b))), e, rtol=1e-5)


@pytest.fixture(scope="module")
def llvm():
    if not mbsdf.llvm_available():
        pytest.skip("Mitsuba's llvm_ad_rgb is unavailable (needs LLVM >= 16: apt-get install "
                    "libllvm19 and DRJIT_LIBLLVM_PATH)")
    mbsdf.register("llvm_ad_rgb")
    import drjit as dr
    return dr


def test_llvm_sampling_estimates_the_albedo_without_bias(plastic, llvm):
    dr = llvm
    bsdf = mi.load_dict({"type": "flashbrdf_tabulated", "filename": str(plastic)})
    wi = np.array([0.5, 0.0, np.sqrt(0.75)])                       # 30 degrees from the normal
    n = 200_000
    rng = np.random.default_rng(1)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(np.tile(wi, (n, 1)).T.astype(np.float32))
    u = rng.random((3, n)).astype(np.float32)
    bs, weight = bsdf.sample(mi.BSDFContext(), si, mi.Float(u[0]), mi.Point2f(u[1:]))
    w = np.array(weight).T
    # pdf() agrees with the density the samples came from
    pdf = np.array(bsdf.pdf(mi.BSDFContext(), si, bs.wo))
    np.testing.assert_allclose(pdf, np.array(bs.pdf), rtol=1e-4)
    # The same albedo by plain cosine sampling in numpy, 4x the samples: the plugin's estimate
    # agrees within 4 combined standard errors (an inconsistent pdf would bias it by far more).
    m = 4 * n
    wo = sample_cosine(rng.random((m, 2)))
    ref = TabulatedBRDF(read_merl(plastic)).evaluate_local(np.tile(wi, (m, 1)), wo) * np.pi
    se = np.sqrt(w.var(axis=0) / n + ref.var(axis=0) / m)
    assert np.all(np.abs(w.mean(axis=0) - ref.mean(axis=0)) < 4 * se)
    # Importance sampling pays against uniform hemisphere sampling (weight 2 pi f cos), which is
    # what the plugin would be without a sampler of its own.
    z = rng.random(m)
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2 * np.pi * rng.random(m)
    wo_u = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)
    uniform = TabulatedBRDF(read_merl(plastic)).evaluate_local(np.tile(wi, (m, 1)), wo_u) \
        * z[:, None] * 2 * np.pi
    assert np.all(w.var(axis=0) < 0.5 * uniform.var(axis=0))


def test_llvm_sphere_matches_our_renderer(plastic, llvm):
    from flashbrdf.render.scene_render import render_sphere, sphere_view
    from tests.conftest import shared_path
    pisa = shared_path("data", "envmaps", "pisa_latlong_256x128.hdr")
    size, spp = 32, 64
    image, stderr = mbsdf.render_sphere_mitsuba(
        {"type": "flashbrdf_tabulated", "filename": str(plastic)}, pisa, size=size, spp=spp)
    ours = render_sphere(read_merl(plastic), pisa, size=size, spp=spp)
    mask = sphere_view(size)[0]
    a, b = image[mask].mean(axis=0), ours[mask].mean(axis=0)
    # The sphere's mean colour: Mitsuba's noise in it is sqrt(sum stderr^2) / n; ours is of the
    # same order. 6 of Mitsuba's standard errors covers both at ~4 sigma, plus 1% for the two
    # renderers' different envmap filtering (bilinear in both, float32 against float64).
    noise = np.sqrt((stderr[mask].astype(float) ** 2).sum(axis=0)) / mask.sum()
    assert np.all(np.abs(a - b) < 6 * noise + 0.01 * b)


@pytest.mark.parametrize("params", [
    {"base_color": [0.6, 0.3, 0.2], "roughness": 0.7, "specular": 0.5},
    {"base_color": [0.9, 0.6, 0.3], "roughness": 0.5, "metallic": 1.0},
    {"base_color": [0.5, 0.05, 0.05], "roughness": 0.5, "clearcoat": 1.0, "clearcoat_gloss": 0.8},
    {"base_color": [0.2, 0.4, 0.2], "roughness": 0.3, "metallic": 0.4, "specular": 0.8,
     "spec_tint": 0.6, "sheen": 0.7, "sheen_tint": 0.5},
    # specular 0: eta = 1, and Mitsuba drops the main lobe, metallic part and all
    {"base_color": [0.9, 0.6, 0.3], "roughness": 0.1, "metallic": 1.0, "specular": 0.0},
    {"base_color": [0.9, 0.6, 0.3], "roughness": 0.1, "metallic": 1.0, "specular": 1e-3},
    # the fit's lower bound (brdf.models.principled_fit): the lobe is there, clear of the edge
    {"base_color": [0.9, 0.6, 0.3], "roughness": 0.1, "metallic": 1.0, "specular": 1e-12},
], ids=["rough_dielectric", "rough_metal", "clearcoat_paint", "everything", "metal_specular_0",
        "metal_specular_1e-3", "metal_specular_fit_bound"])
def test_numpy_principled_is_mitsubas(params, llvm):
    """brdf.models.principled against Mitsuba 3's own `principled` plugin, f cos theta_o."""
    from flashbrdf.brdf.models.principled import principled_brdf_local
    dr = llvm
    bsdf = mi.load_dict({"type": "principled", **{k: ({"type": "rgb", "value": v}
                                                      if k == "base_color" else v)
                                                  for k, v in params.items()}})
    rng = np.random.default_rng(2)
    n = 4000
    wi, wo = _directions(rng, n), _directions(rng, n)
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.wi = mi.Vector3f(wi.T.astype(np.float32))
    got = np.array(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(wo.T.astype(np.float32)))).T
    expected = principled_brdf_local(wi.astype(np.float32), wo.astype(np.float32), params) \
        * wo[:, 2:3]
    # float32 in Mitsuba against float64 here: 1e-3 relative, and an absolute floor for values
    # that are differences of nearly equal terms.
    np.testing.assert_allclose(got, expected, rtol=1e-3, atol=1e-5)


def test_drjit_bin_lookup_agrees_with_the_numpy_one():
    """The plugin's Dr.Jit copy of the angle-to-bin code (merl_index) against
    brdf.angles.merl_flat_index_local on 2000 random local pairs with θd > 1° (φd is undefined
    at θd = 0). scalar_rgb computes in float32, so a pair sitting on a bin edge may land one bin
    over: at most 0.5% of pairs may differ, each by one bin in θh, θd or φd."""
    from flashbrdf.brdf.angles import merl_flat_index_local
    from flashbrdf.brdf.rusinkiewicz import half_diff_from_local
    mbsdf.register("scalar_rgb")
    merl_index = mbsdf._plugin_class().merl_index
    rng = np.random.default_rng(3)
    wi, wo = _directions(rng, 4000), _directions(rng, 4000)
    theta_d = half_diff_from_local(wi, wo)[1]
    keep = theta_d > np.radians(1.0)
    wi, wo = wi[keep][:2000], wo[keep][:2000]
    ours = merl_flat_index_local(wi, wo)
    theirs = np.array([int(merl_index(mi.Vector3f(*a), mi.Vector3f(*b))) for a, b in zip(wi, wo)])
    ijk = lambda flat: np.stack([flat // (90 * 180), flat // 180 % 90, flat % 180])  # noqa: E731
    step = np.abs(ijk(ours) - ijk(theirs))
    step[2] = np.minimum(step[2], 180 - step[2])   # φd wraps at 180°
    assert (ours != theirs).mean() <= 0.005
    assert step.max() <= 1


def test_register_names_the_variants_when_given_another():
    """register(42) raised Mitsuba's TypeError about str.join; now a ValueError naming the
    variants, as for a name Mitsuba lacks (its own ImportError lists them too)."""
    with pytest.raises(ValueError, match=r"variant must be one of .*scalar_rgb.*; got 42"):
        mbsdf.register(42)
    with pytest.raises(ValueError, match="got 'scalar_rbg'"):
        mbsdf.register("scalar_rbg")
