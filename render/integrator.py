"""Direct lighting of shading points: point, directional and environment-map lights.

Inputs are plain arrays over P shading points (trimesh style):
    points (P, 3) world, normals (P, 3) unit shading normals, view (P, 3) unit directions from the
    surface toward the camera (omega_o).
Outputs are (P, 3) pixel values under the contract's pixel model (direct light only):
    point:       V rho I cos(theta_i) / r^2
    directional: V rho E cos(theta_i)
    envmap:      integral of V(w) rho L(w) cos(theta_i) dw, by Monte Carlo with multiple
                 importance sampling (luminance-sampled envmap + BRDF sampling, balance or power
                 heuristic), randomised QMC (Sobol net + per-pixel Cranley-Patterson shift).
`occluded(points (N,3), directions (N,3), max_distance (N,) or None) -> (N,) bool` casts shadow
rays from the surface points (it owns the self-intersection offset, as capture.occluded does;
max_distance None = unbounded). occluded=None: convex geometry, nothing is occluded.
"""

import concurrent.futures

import numpy as np
from tqdm import tqdm

from flashbrdf.brdf.frame import Frame
from flashbrdf.files.threads import thread_budget
from flashbrdf.render.envmap import EnvMap

# Pixel-samples per work item: keeps each thread's temporaries around 100-200 MB.
SAMPLES_PER_CHUNK = 1 << 17


def _dot(a, b):
    return np.einsum("...k,...k->...", a, b)


def _as_rows(*arrays):
    """(P, 3) float arrays (lists, or one (3,) point, accepted)."""
    return [np.atleast_2d(np.asarray(a, dtype=float)) for a in arrays]


def render_point_light(points, normals, view, brdf, light_position, intensity_rgb, occluded=None):
    """Point light at `light_position` (3,) world: V rho I cos(theta_i) / r^2 -> (P, 3), for
    points, normals, view (P, 3) world (view: unit vectors toward the eye)."""
    points, normals, view = _as_rows(points, normals, view)
    to_light = np.asarray(light_position, float)[None] - points
    r2 = np.maximum(_dot(to_light, to_light), 1e-300)
    r = np.sqrt(r2)
    wi = to_light / r[:, None]
    irradiance = np.asarray(intensity_rgb, float)[None] / r2[:, None]
    return _direct(points, normals, view, brdf, wi, irradiance, r, occluded)


def render_directional_light(points, normals, view, brdf, direction, irradiance_rgb,
                             occluded=None):
    """Directional light toward `direction` (3,) world with irradiance E: V rho E cos -> (P, 3),
    for points, normals, view (P, 3) world."""
    points, normals, view = _as_rows(points, normals, view)
    d = np.asarray(direction, float)
    wi = np.broadcast_to(d / np.linalg.norm(d), points.shape)
    irradiance = np.broadcast_to(np.asarray(irradiance_rgb, float), points.shape)
    return _direct(points, normals, view, brdf, wi, irradiance, None, occluded)


def _direct(points, normals, view, brdf, wi, irradiance, distance, occluded):
    frame = Frame.from_normal(normals)
    wi_l, wo_l = frame.to_local(wi), frame.to_local(view)
    cos_i = np.maximum(wi_l[:, 2], 0.0)
    value = brdf.evaluate_local(wi_l, wo_l) * (irradiance * cos_i[:, None])
    if occluded is not None:
        lit = np.any(value > 0, axis=1)
        idx = np.nonzero(lit)[0]
        if idx.size:
            blocked = occluded(points[idx], wi[idx], None if distance is None else distance[idx])
            value[idx[blocked]] = 0.0
    return value


def sample_pattern(spp, dims, seed):
    """(spp, dims) low-discrepancy points in [0,1), deterministic in `seed`.

    Each pair of dimensions is the first N points of the 2D Sobol (0,2)-sequence in base 2
    (van der Corput and its Sobol partner), randomised by a digital XOR shift drawn from the seed.
    Pixels then add their own random Cranley-Patterson shift, which keeps every estimate
    unbiased. (Built here because importing scipy.stats costs seconds per process.)
    """
    index = np.arange(spp, dtype=np.uint64)
    van_der_corput = np.zeros(spp, dtype=np.uint64)
    partner = np.zeros(spp, dtype=np.uint64)
    v = np.uint64(1 << 31)
    for bit in range(32):
        on = ((index >> np.uint64(bit)) & np.uint64(1)).astype(bool)
        van_der_corput[on] ^= np.uint64(1 << (31 - bit))
        partner[on] ^= v
        v = v ^ (v >> np.uint64(1))               # direction numbers of the polynomial x + 1
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x50B01])
    out = np.empty((spp, dims))
    for d in range(dims):
        base = van_der_corput if d % 2 == 0 else partner
        shift = np.uint64(rng.integers(0, 1 << 32))
        out[:, d] = (base ^ shift).astype(np.float64) / 2.0 ** 32
    return out


def render_envmap(points, normals, view, brdf, envmap, spp=64, seed=0, occluded=None,
                  heuristic="balance", strategies=("envmap", "brdf"), threads=None,
                  progress=None):
    """Environment-map lighting -> (P, 3).

    spp: samples per pixel; as in pbrt's and Mitsuba's direct-lighting integrators, each sample
    draws one direction from every strategy (one envmap and one BRDF direction with MIS).
    Deterministic for a given seed, whatever the thread count.
    progress: a tqdm description string to show a progress bar, or None.
    """
    points = np.asarray(points, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    view = np.asarray(view, dtype=np.float64)
    n_points = len(points)
    out = np.zeros((n_points, 3))
    if n_points == 0:
        return out
    strategies = tuple(strategies)
    if strategies == ("envmap",) and getattr(envmap, "compensate", False):
        # Compensated sampling skips the map's dim part, which only BRDF samples may cover.
        envmap = EnvMap(envmap.pixels, envmap.world_from_envmap, 1.0, compensate=False)
    if "envmap" in strategies and not getattr(envmap, "can_sample", True):
        strategies = tuple(x for x in strategies if x != "envmap") or ("brdf",)
    per_strategy = max(1, int(spp))
    pattern = sample_pattern(per_strategy, 2 * len(strategies), seed)
    step = max(1, SAMPLES_PER_CHUNK // (per_strategy * len(strategies)))
    starts = list(range(0, n_points, step))

    def work(start):
        stop = min(start + step, n_points)
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, start])
        shift = rng.random((stop - start, 1, pattern.shape[1]))
        u = pattern[None] + shift                               # (Pc, S, 2 * strategies)
        u -= u >= 1.0                                           # wrap (np.mod is slow)
        out[start:stop] = _envmap_chunk(points[start:stop], normals[start:stop],
                                        view[start:stop], brdf, envmap, u, occluded,
                                        heuristic, strategies)
        return stop - start

    threads = threads or thread_budget(2)
    bar = None
    if progress:
        bar = tqdm(total=n_points, desc=progress, unit="px", disable=None, leave=False)
    try:
        if threads == 1 or len(starts) == 1:
            for s in starts:
                done = work(s)
                if bar is not None:
                    bar.update(done)
        else:
            with concurrent.futures.ThreadPoolExecutor(threads) as pool:
                for done in pool.map(work, starts):
                    if bar is not None:
                        bar.update(done)
    finally:
        if bar is not None:
            bar.close()
    return out


def _mis_factor(pdf_this, pdf_other, heuristic):
    """f L cos / pdf_this * w(this)  ==  f L cos * factor; returns factor (balance or power)."""
    if heuristic == "balance":
        return 1.0 / np.maximum(pdf_this + pdf_other, 1e-300)
    if heuristic == "power":
        return pdf_this / np.maximum(pdf_this ** 2 + pdf_other ** 2, 1e-300)
    raise ValueError(f"unknown heuristic {heuristic!r}")


def _envmap_chunk(points, normals, view, brdf, envmap, u, occluded, heuristic, strategies):
    """Both MIS strategies for a chunk of Pc points and S samples each -> (Pc, 3).

    Works on flat (Pc * S, ...) arrays: boolean compression of flat arrays is much cheaper than
    fancy indexing of (Pc, S) ones.
    """
    pc, s = u.shape[:2]
    frame = Frame.from_normal(normals)
    wo_l = np.repeat(frame.to_local(view), s, axis=0)                 # (Pc*S, 3)
    frames = Frame(*(np.repeat(x, s, axis=0) for x in (frame.tangent, frame.bitangent,
                                                       frame.normal)))    # one per sample
    pixel = np.repeat(np.arange(pc), s)
    u = u.reshape(pc * s, -1)
    both = "envmap" in strategies and "brdf" in strategies
    total = np.zeros((pc, 3))
    for k, strategy in enumerate(strategies):
        uk = u[:, 2 * k:2 * k + 2]
        if strategy == "envmap":
            wi_w, pdf_env = envmap.sample(uk)
            wi_l = frames.to_local(wi_w)
            factor = (_mis_factor(pdf_env, brdf.pdf_local(wi_l, wo_l), heuristic) if both
                      else 1.0 / np.maximum(pdf_env, 1e-300))
        elif strategy == "brdf":
            wi_l, pdf_brdf = brdf.sample_local(wo_l, uk)
            wi_w = frames.to_world(wi_l)
            factor = (_mis_factor(pdf_brdf, envmap.pdf(wi_w), heuristic) if both
                      else 1.0 / np.maximum(pdf_brdf, 1e-300))
        else:
            raise ValueError(f"unknown strategy {strategy!r}")
        # Only directions above the horizon can contribute: evaluate those alone.
        live = wi_l[:, 2] > 0
        if not np.any(live):
            continue
        wi_live, wo_live = wi_l[live], wo_l[live]
        f = brdf.evaluate_local(wi_live, wo_live)
        contrib = f * (wi_live[:, 2] * np.broadcast_to(factor, live.shape)[live])[:, None]
        keep = np.any(contrib > 0, axis=1)
        contrib = contrib[keep]
        dirs = wi_w[live][keep]
        owner = pixel[live][keep]
        contrib *= envmap.radiance(dirs)
        if occluded is not None and len(owner):
            contrib[occluded(points[owner], dirs, None)] = 0.0
        for c in range(3):
            total[:, c] += np.bincount(owner, contrib[:, c], minlength=pc)
    return total / s
