"""The BRDF interface every model answers, as Mitsuba 3's and pbrt's BSDFs do: eval, sample, pdf.

Every model works in the local shading frame (normal = +z; isotropic, so no tangent is needed):
    evaluate_local(wi, wo) -> (..., 3) in 1/sr, 0 where wi or wo is below the horizon
    sample_local(wo, u)    -> wi (..., 3), pdf (...) solid-angle density (wi may come back below
                              the horizon: the caller's f = 0 discards it, the pdf stays valid)
    pdf_local(wi, wo)      -> (...) the solid-angle density of sample_local
and the same in world space about a normal: evaluate, sample, pdf (brdf.frame.Frame).
wi points toward the light, wo toward the viewer; all vectors are unit (..., 3); u (..., 2) in
[0, 1).
"""

import numpy as np

from flashbrdf.brdf.frame import Frame

INV_PI = 1.0 / np.pi
LUMINANCE_RGB = np.array([0.2126, 0.7152, 0.0722])  # linear sRGB (Rec. 709) luminance weights


def sample_cosine(u):
    """Cosine-weighted hemisphere directions (..., 3) for u (..., 2); pdf = cos / pi."""
    r = np.sqrt(u[..., 0])
    phi = 2.0 * np.pi * u[..., 1]
    z = np.sqrt(np.maximum(0.0, 1.0 - u[..., 0]))
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def reflect(wo, h):
    """wo (..., 3) mirrored about the unit half vector h (..., 3)."""
    return 2.0 * np.sum(wo * h, axis=-1, keepdims=True) * h - wo


def half_vector(wi, wo):
    """The unit half vector (..., 3) of two unit directions (0 where they are opposite)."""
    h = wi + wo
    return h / np.maximum(np.linalg.norm(h, axis=-1, keepdims=True), 1e-300)


def luminance(rgb):
    """Linear sRGB luminance of one (3,) colour, a float."""
    return float(np.dot(np.asarray(rgb, float), LUMINANCE_RGB))


class BRDFModel:
    """Base class: subclasses define the three local-frame methods; the world-space ones follow."""

    def evaluate_local(self, wi, wo):
        raise NotImplementedError

    def sample_local(self, wo, u):
        raise NotImplementedError

    def pdf_local(self, wi, wo):
        raise NotImplementedError

    def evaluate(self, wi, wo, normal):
        """rho (..., 3) in 1/sr of world directions about a world normal (..., 3)."""
        frame = Frame.from_normal(normal)
        return self.evaluate_local(frame.to_local(wi), frame.to_local(wo))

    def sample(self, wo, u, normal):
        """(wi (..., 3) world, pdf (...)) drawn for the world direction wo about `normal`."""
        frame = Frame.from_normal(normal)
        wi, pdf = self.sample_local(frame.to_local(wo), u)
        return frame.to_world(wi), pdf

    def pdf(self, wi, wo, normal):
        """The solid-angle density (...) of `sample` for world directions about `normal`."""
        frame = Frame.from_normal(normal)
        return self.pdf_local(frame.to_local(wi), frame.to_local(wo))


class HalfVectorMixture(BRDFModel):
    """Sampling shared by GGX and tabulated BRDFs: a cosine-weighted direction with probability
    `cosine_fraction`, else omega_o reflected about a half vector from the subclass's
    `sample_half_vector(u)`; `pdf_local` is the subclass's mixture density."""

    cosine_fraction = 0.25

    def sample_half_vector(self, u):
        raise NotImplementedError

    def sample_local(self, wo, u):
        c = self.cosine_fraction
        use_cos = u[..., 0] < c
        # Reuse the component-selecting uniform so stratification survives.
        u_cos = np.stack([np.where(use_cos, u[..., 0] / max(c, 1e-300), 0.0), u[..., 1]], -1)
        u_h = np.stack([np.where(use_cos, 0.0, (u[..., 0] - c) / max(1.0 - c, 1e-300)),
                        u[..., 1]], -1)
        wo_b = np.broadcast_to(wo, np.broadcast_shapes(wo.shape, u.shape[:-1] + (3,)))
        wi = np.where(use_cos[..., None], sample_cosine(u_cos),
                      reflect(wo_b, self.sample_half_vector(u_h)))
        return wi, self.pdf_local(wi, wo_b)
