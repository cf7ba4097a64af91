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

`brdf` is one model, or a list or tuple of models: then one output per model, and what does not
depend on the BRDF (frames, the envmap strategy's directions, pdfs and radiance, shadow rays) is
computed once for all of them. Each model's output equals its render alone, bit for bit.
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


def _models(brdf):
    """(list of models, whether `brdf` was a list or tuple of them)."""
    several = isinstance(brdf, (list, tuple))
    return (list(brdf) if several else [brdf]), several


def render_point_light(points, normals, view, brdf, light_position, intensity_rgb, occluded=None):
    """Point light at `light_position` (3,) world: V rho I cos(theta_i) / r^2 -> (P, 3), for
    points, normals, view (P, 3) world (view: unit vectors toward the eye); a list of (P, 3), one
    per model, when brdf is a list of models."""
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
    for points, normals, view (P, 3) world (a list of them for a list of models)."""
    points, normals, view = _as_rows(points, normals, view)
    d = np.asarray(direction, float)
    wi = np.broadcast_to(d / np.linalg.norm(d), points.shape)
    irradiance = np.broadcast_to(np.asarray(irradiance_rgb, float), points.shape)
    return _direct(points, normals, view, brdf, wi, irradiance, None, occluded)


def _direct(points, normals, view, brdf, wi, irradiance, distance, occluded):
    models, several = _models(brdf)
    if not models:
        return []
    frame = Frame.from_normal(normals)
    wi_l, wo_l = frame.to_local(wi), frame.to_local(view)
    cos_i = np.maximum(wi_l[:, 2], 0.0)
    incident = irradiance * cos_i[:, None]
    values = [model.evaluate_local(wi_l, wo_l) * incident for model in models]
    if occluded is not None:
        lit = [np.any(value > 0, axis=1) for value in values]
        idx = np.nonzero(np.logical_or.reduce(lit))[0]      # one shadow ray a point, for all
        if idx.size:
            blocked = occluded(points[idx], wi[idx], None if distance is None else distance[idx])
            for value, mine in zip(values, lit):
                value[idx[blocked & mine[idx]]] = 0.0
    return values if several else values[0]


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
                  progress=None, emit=None):
    """Environment-map lighting -> (P, 3), or a list of (P, 3), one per model, for a list of
    models (each equal to that model's render alone: the same seed gives it the same samples).

    spp: samples per pixel; as in pbrt's and Mitsuba's direct-lighting integrators, each sample
    draws one direction from every strategy (one envmap and one BRDF direction with MIS).
    Deterministic for a given seed, whatever the thread count.
    progress: a tqdm description string to show a progress bar, or None.
    emit: None, or emit(rows, m, values) takes each chunk's values (n, 3) float64 of model m
    for points[rows] (a slice) as it is done, and nothing is returned: the caller keeps what it
    needs (render_scene, float32 pixels), not a (P, 3) float64 array per model. It is called
    from the render's threads, for disjoint rows.
    """
    models, several = _models(brdf)
    points = np.asarray(points, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    view = np.asarray(view, dtype=np.float64)
    n_points = len(points)
    outs = None
    if emit is None:
        outs = [np.zeros((n_points, 3)) for _ in models]

        def emit(rows, m, values):
            outs[m][rows] = values
    if n_points == 0 or not models:
        return None if outs is None else (outs if several else outs[0])
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
        values = _envmap_chunk(points[start:stop], normals[start:stop], view[start:stop],
                               models, envmap, u, occluded, heuristic, strategies)
        for m, value in enumerate(values):
            emit(slice(start, stop), m, value)
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
    return None if outs is None else (outs if several else outs[0])


def _mis_factor(pdf_this, pdf_other, heuristic):
    """f L cos / pdf_this * w(this)  ==  f L cos * factor; returns factor (balance or power)."""
    if heuristic == "balance":
        return 1.0 / np.maximum(pdf_this + pdf_other, 1e-300)
    if heuristic == "power":
        return pdf_this / np.maximum(pdf_this ** 2 + pdf_other ** 2, 1e-300)
    raise ValueError(f"unknown heuristic {heuristic!r}")


def _envmap_chunk(points, normals, view, models, envmap, u, occluded, heuristic, strategies):
    """Both MIS strategies for a chunk of Pc points and S samples each -> [(Pc, 3) per model].

    The envmap strategy's directions, pdfs, radiance and shadow rays are the same for every
    model: computed once, the radiance and shadow rays for the directions some model can use.
    The BRDF strategy's directions are each model's own. Works on flat (Pc * S, ...) arrays:
    boolean compression of flat arrays is much cheaper than fancy indexing of (Pc, S) ones.
    """
    pc, s = u.shape[:2]
    frame = Frame.from_normal(normals)
    wo_l = np.repeat(frame.to_local(view), s, axis=0)                 # (Pc*S, 3)
    frames = Frame(*(np.repeat(x, s, axis=0) for x in (frame.tangent, frame.bitangent,
                                                       frame.normal)))    # one per sample
    pixel = np.repeat(np.arange(pc), s)
    u = u.reshape(pc * s, -1)
    both = "envmap" in strategies and "brdf" in strategies
    totals = [np.zeros((pc, 3)) for _ in models]
    for k, strategy in enumerate(strategies):
        uk = u[:, 2 * k:2 * k + 2]
        if strategy == "envmap":
            wi_w, pdf_env = envmap.sample(uk)
            wi_l = frames.to_local(wi_w)
            factors = [_mis_factor(pdf_env, model.pdf_local(wi_l, wo_l), heuristic) if both
                       else 1.0 / np.maximum(pdf_env, 1e-300) for model in models]
            _add_light(totals, models, points, pixel, wi_w, wi_l, wo_l, factors, envmap,
                       occluded)
        elif strategy == "brdf":
            for m, model in enumerate(models):
                wi_l, pdf_brdf = model.sample_local(wo_l, uk)
                wi_w = frames.to_world(wi_l)
                factor = (_mis_factor(pdf_brdf, envmap.pdf(wi_w), heuristic) if both
                          else 1.0 / np.maximum(pdf_brdf, 1e-300))
                _add_light(totals[m:m + 1], [model], points, pixel, wi_w, wi_l, wo_l, [factor],
                           envmap, occluded)
        else:
            raise ValueError(f"unknown strategy {strategy!r}")
    return [total / s for total in totals]


def _add_light(totals, models, points, pixel, wi_w, wi_l, wo_l, factors, envmap, occluded):
    """Add f L cos * factor of the sampled directions wi (world wi_w, local wi_l) to each
    model's (Pc, 3) total, per pixel; radiance and shadow rays once for the directions any model
    lights (its contribution > 0)."""
    # Only directions above the horizon can contribute: evaluate those alone.
    live = wi_l[:, 2] > 0
    if not np.any(live):
        return
    wi_live, wo_live = wi_l[live], wo_l[live]
    contribs, keeps = [], []
    for model, factor in zip(models, factors):
        f = model.evaluate_local(wi_live, wo_live)
        contrib = f * (wi_live[:, 2] * np.broadcast_to(factor, live.shape)[live])[:, None]
        keep = np.any(contrib > 0, axis=1)
        contribs.append(contrib[keep])
        keeps.append(keep)
    used = keeps[0] if len(keeps) == 1 else np.logical_or.reduce(keeps)
    dirs = wi_w[live][used]
    owner = pixel[live][used]
    radiance = envmap.radiance(dirs)
    blocked = (occluded(points[owner], dirs, None) if occluded is not None and len(owner)
               else None)
    pc = len(totals[0])
    for total, contrib, keep in zip(totals, contribs, keeps):
        mine = keep[used]
        whole = len(contrib) == len(owner)                      # this model lights them all
        contrib *= radiance if whole else radiance[mine]
        if blocked is not None:
            contrib[blocked if whole else blocked[mine]] = 0.0
        mine_owner = owner if whole else owner[mine]
        for c in range(3):
            total[:, c] += np.bincount(mine_owner, contrib[:, c], minlength=pc)
