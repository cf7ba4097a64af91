"""The Mitsuba 3 BSDF plugin `flashbrdf_tabulated`: a MERL `.binary` table, as our renderer reads it.

    import mitsuba as mi; mi.set_variant("llvm_ad_rgb")      # or "scalar_rgb"
    import flashbrdf.render.mitsuba_bsdf as m; m.register()
    bsdf = mi.load_dict({"type": "flashbrdf_tabulated", "filename": "brdf.binary"})

- eval: the table at the nearest MERL bin (brdf.models.TabulatedBRDF's lookup, written with
  drjit so that llvm_ad_rgb evaluates whole wavefronts), times cos theta_o; 0 below the horizon.
- sample / pdf: TabulatedBRDF's own strategy, with split_diffuse. A cosine-weighted direction
  with probability `cosine_fraction` (the diffuse floor's share of the albedo), else the viewer
  direction reflected about a half vector drawn from the table's theta_h marginal less that floor
  (piecewise constant over the 90 theta_h bins, uniform in solid angle within a bin). It is a
  tabulated microfacet distribution: it follows the table's highlight at every roughness, as
  roughplastic's GGX lobe follows its alpha, without fitting an alpha.
- In scalar_rgb Mitsuba calls the plugin once per sample, from Python: fine for a few
  directions, far too slow for an image. llvm_ad_rgb is the real target.

LLVM: drjit needs LLVM >= 16 ("Cannot select: fminimum" with Debian 12's 14/15). On Debian 12,
`apt-get install libllvm19`; this module points DRJIT_LIBLLVM_PATH at it when that library is
there and the variable is unset (it must be set before drjit first uses LLVM).
"""

import functools
import os
import subprocess
import sys

import numpy as np

from flashbrdf.brdf.merl import read_merl
from flashbrdf.brdf.models import TabulatedBRDF
from flashbrdf.render.scene_render import sphere_view

# mitsuba and drjit (the optional [mitsuba] extra) load inside the functions that need them, so
# this module imports (and says what is missing) without them.
LIBLLVM19 = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"
PLUGIN_NAME = "flashbrdf_tabulated"

if "DRJIT_LIBLLVM_PATH" not in os.environ and os.path.exists(LIBLLVM19):
    os.environ["DRJIT_LIBLLVM_PATH"] = LIBLLVM19


@functools.lru_cache(maxsize=None)
def llvm_available():
    """True when Mitsuba's llvm_ad_rgb variant can be set (mitsuba installed, a usable LLVM).
    Probed in a child process, once per process: with LLVM 14/15 the probe's op does not raise,
    it aborts the whole process ("LLVM ERROR: Cannot select"), which no except can catch."""
    try:
        import mitsuba as mi
        if "llvm_ad_rgb" not in mi.variants():
            return False
    except Exception:   # any failure (import, missing library) means "not available"
        return False
    probe = ("import mitsuba as mi, drjit as dr; mi.set_variant('llvm_ad_rgb'); "
             "dr.eval(dr.minimum(mi.Float([1.0, 2.0]), 1.5))")  # the op that fails on LLVM 14/15
    try:
        done = subprocess.run([sys.executable, "-c", probe], capture_output=True, timeout=300)
    except (OSError, subprocess.SubprocessError):
        return False
    return done.returncode == 0


def register(variant=None):
    """Register `flashbrdf_tabulated` with Mitsuba 3 for the current variant.

    variant: set this variant first; with none set yet, llvm_ad_rgb when available, else
    scalar_rgb. Call again after switching variants (plugins are per variant).
    """
    try:
        import mitsuba as mi
    except ImportError as err:
        raise ImportError("Mitsuba 3 is not installed: `pip install mitsuba` (in a checkout: "
                          "`pip install -e \".[mitsuba]\"`)") from err
    if variant is not None:
        if variant not in mi.variants():  # Mitsuba's own message for 42 is about str.join
            raise ValueError(f"variant must be one of {', '.join(mi.variants())}; got {variant!r}")
        mi.set_variant(variant)
    elif mi.variant() is None:
        mi.set_variant("llvm_ad_rgb" if llvm_available() else "scalar_rgb")
    mi.register_bsdf(PLUGIN_NAME, lambda props: _plugin_class()(props))
    return mi.variant()


def _plugin_class():
    """The BSDF class for the current variant (mi.BSDF differs per variant)."""
    import drjit as dr
    import mitsuba as mi


    jit = dr.is_jit_v(mi.Float)

    def storage(values):
        values = np.ascontiguousarray(values, dtype=np.float32)
        return mi.Float(values) if jit else values

    def gather_float(source, index):
        return dr.gather(mi.Float, source, index) if jit else mi.Float(source[int(index)])

    def gather_rgb(source, index):
        if jit:
            return dr.gather(mi.Color3f, source, index)
        k = int(index) * 3
        return mi.Color3f(*(float(v) for v in source[k:k + 3]))

    def theta_h_bin(cos_h):
        theta_h = dr.acos(dr.clip(cos_h, -1.0, 1.0))
        return mi.UInt32(dr.clip(dr.sqrt(theta_h * (2.0 / dr.pi)) * 90.0, 0.0, 89.0))

    def merl_index(wi, wo):
        """The flat MERL bin of a local-frame pair: brdf.models.merl_flat_index_local."""
        h = dr.normalize(wi + wo)
        sin_h = dr.sqrt(dr.maximum(h.x * h.x + h.y * h.y, 0.0))
        theta_h = dr.atan2(sin_h, h.z)
        i = dr.minimum(dr.sqrt(theta_h * (180.0 / dr.pi)) * np.sqrt(90.0), 89.0)
        j = dr.minimum(dr.acos(dr.clip(dr.dot(wi, h), -1.0, 1.0)) * (180.0 / dr.pi), 89.0)
        safe = sin_h > 1e-7
        inv = dr.rcp(dr.select(safe, sin_h, 1.0))
        px = dr.select(safe, h.x * inv, 1.0)
        py = dr.select(safe, h.y * inv, 0.0)
        along_t = h.z * (wi.x * px + wi.y * py) - sin_h * wi.z
        along_b = wi.y * px - wi.x * py
        phi_d = dr.atan2(along_b, along_t)
        phi_d = dr.select(phi_d < 0.0, phi_d + dr.pi, phi_d)
        k = dr.minimum(phi_d * (180.0 / dr.pi), 179.0)
        return (mi.UInt32(i) * 90 + mi.UInt32(j)) * 180 + mi.UInt32(k)

    class FlashbrdfTabulated(mi.BSDF):
        """A MERL table (parameter `filename`) with TabulatedBRDF's lookup and sampling."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            self.filename = str(props["filename"])
            table = read_merl(self.filename)
            model = TabulatedBRDF(table, split_diffuse=True)
            prob, cos_edges, density, cosine_fraction = model.half_vector_distribution()
            self.m_table = storage(np.nan_to_num(table, nan=0.0).reshape(-1))
            self.m_cos_edges = storage(cos_edges)
            self.m_density = storage(density)
            self.m_h_distribution = mi.DiscreteDistribution(
                np.ascontiguousarray(prob, dtype=np.float32))
            self.m_cosine_fraction = float(cosine_fraction)
            flags = (mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.DiffuseReflection
                     | mi.BSDFFlags.FrontSide)
            self.m_components = [flags]
            self.m_flags = flags

        def _value(self, si, wo, active):
            cos_i, cos_o = mi.Frame3f.cos_theta(si.wi), mi.Frame3f.cos_theta(wo)
            active = active & (cos_i > 0.0) & (cos_o > 0.0)
            rho = gather_rgb(self.m_table, merl_index(si.wi, wo)) if jit or active \
                else mi.Color3f(0.0)
            return dr.select(active, rho * cos_o, 0.0)

        def eval(self, ctx, si, wo, active=True):
            return self._value(si, wo, active)

        def pdf(self, ctx, si, wo, active=True):
            cos_i, cos_o = mi.Frame3f.cos_theta(si.wi), mi.Frame3f.cos_theta(wo)
            active = active & (cos_i > 0.0) & (cos_o > 0.0)
            h = dr.normalize(si.wi + wo)
            wo_h = dr.dot(wo, h)
            h_ok = active & (wo_h > 0.0) & (h.z > 0.0)
            density = gather_float(self.m_density, theta_h_bin(h.z)) if jit or h_ok else 0.0
            h_pdf = dr.select(h_ok, density / (4.0 * dr.maximum(wo_h, 1e-12)), 0.0)
            cos_pdf = mi.warp.square_to_cosine_hemisphere_pdf(wo)
            c = self.m_cosine_fraction
            return dr.select(active, c * cos_pdf + (1.0 - c) * h_pdf, 0.0)

        def eval_pdf(self, ctx, si, wo, active=True):
            return self.eval(ctx, si, wo, active), self.pdf(ctx, si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            cos_i = mi.Frame3f.cos_theta(si.wi)
            active = active & (cos_i > 0.0)
            c = self.m_cosine_fraction
            use_cos = sample1 < c
            wo_cos = mi.warp.square_to_cosine_hemisphere(sample2)
            index, u = self.m_h_distribution.sample_reuse(sample2.x)
            lo = gather_float(self.m_cos_edges, index)
            hi = gather_float(self.m_cos_edges, index + 1)
            cos_t = lo + u * (hi - lo)
            sin_t = dr.sqrt(dr.maximum(1.0 - cos_t * cos_t, 0.0))
            sin_p, cos_p = dr.sincos(2.0 * dr.pi * sample2.y)
            h = mi.Vector3f(sin_t * cos_p, sin_t * sin_p, cos_t)
            wo_h = 2.0 * dr.dot(si.wi, h) * h - si.wi
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = dr.select(use_cos, wo_cos, wo_h)
            bs.pdf = self.pdf(ctx, si, bs.wo, active)
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            active = active & (bs.pdf > 0.0) & (mi.Frame3f.cos_theta(bs.wo) > 0.0)
            value = self._value(si, bs.wo, active)
            weight = dr.select(active, value / dr.maximum(bs.pdf, 1e-20), 0.0)
            return bs, weight

        def traverse(self, callback):
            pass

        def to_string(self):
            return f"FlashbrdfTabulated[filename={self.filename!r}]"

    FlashbrdfTabulated.merl_index = staticmethod(merl_index)  # for the agreement test
    return FlashbrdfTabulated


def render_sphere_mitsuba(bsdf, envmap_path, size=128, spp=64, seed=0, spp_per_pass=64):
    """render.scene_render.render_sphere's picture, rendered by Mitsuba 3's `path` integrator.

    bsdf: a Mitsuba BSDF dict (e.g. {"type": "flashbrdf_tabulated", "filename": ...}). The same
    unit sphere, orthographic view along -z through pixel centres and lat-long map (Mitsuba's
    envmap reads u = atan2(x, -z) / 2pi, ours 0.5 + that, hence the 180-degree turn about y);
    max_depth 2 is direct lighting, with Mitsuba's MIS of envmap and BSDF samples.
    Returns (image (size, size, 3) float32, standard error of each pixel's mean (size, size, 3)).
    Needs a JIT variant (llvm_ad_rgb) already set, and the plugin registered.
    """
    import drjit as dr
    import mitsuba as mi

    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "path", "max_depth": 2},
        "emitter": {"type": "envmap", "filename": os.fspath(envmap_path),
                    "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], 180)},
        "sphere": {"type": "sphere", "bsdf": bsdf}})
    integrator = scene.integrator()
    mask, normals, _ = sphere_view(size)
    n_pix = normals.shape[0]
    chunk = max(1, min(spp, spp_per_pass))
    origin = np.concatenate([normals[:, :2], np.full((n_pix, 1), 5.0)], axis=1)
    origin = np.tile(origin, (chunk, 1)).astype(np.float32)
    ray = mi.Ray3f(mi.Point3f(origin.T), mi.Vector3f(0.0, 0.0, -1.0))
    total = np.zeros((n_pix, 3))
    total_sq = np.zeros((n_pix, 3))
    done, k = 0, 0
    while done < spp:
        sampler = mi.load_dict({"type": "independent"})
        sampler.seed(seed * 1_000_003 + k, n_pix * chunk)
        value, _, _ = integrator.sample(scene, sampler, ray)
        values = np.array(value, dtype=np.float64).reshape(3, chunk, n_pix)
        values = np.moveaxis(values, 0, -1)
        take = min(chunk, spp - done)
        total += values[:take].sum(axis=0)
        total_sq += (values[:take] ** 2).sum(axis=0)
        done += take
        k += 1
        dr.flush_malloc_cache()
    mean = total / spp
    stderr = np.sqrt(np.maximum(total_sq / spp - mean ** 2, 0.0) / max(spp - 1, 1))
    image = np.zeros((size, size, 3), dtype=np.float32)
    error = np.zeros((size, size, 3), dtype=np.float32)
    image[mask], error[mask] = mean, stderr
    return image, error
