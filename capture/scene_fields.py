"""Typed reading of one JSON object of scene.json: every bad value raises InputError naming the
file and the full field path, e.g. "…/scene.json: photos[2].light.position: expected 3 numbers".
"""

import math
import sys

import numpy as np

from flashbrdf.files.errors import InputError

ROTATION_ATOL = 1e-4
# Photos are float32 (up to 3.4e38, normal down to 1.2e-38), and so are the rays Embree traces: a
# scale, intensity, exposure or intrinsic outside this range turned them to inf or to 0 (a slice
# of zeros, a render of inf, with exit 0). Far beyond any camera or light.
MIN_FACTOR, MAX_FACTOR = 1e-30, 1e30
# Positions (camera centres, light positions, mesh vertices) and principal points: any magnitude
# up to this, 0 included; past it, float32 rays and pixel coordinates turn to inf.
MAX_COORDINATE = 1e30


def beyond_coordinates(values):
    """The first of `values` (any shape) past ±MAX_COORDINATE (inf included), or None."""
    values = np.ravel(np.asarray(values, dtype=np.float64))
    odd = values[~(np.abs(values) <= MAX_COORDINATE)]
    return float(odd[0]) if odd.size else None


def principal_point_problem(centre, size, focal):
    """Why a principal point `centre` (pixels) of an image axis of `size` pixels cannot go with
    focal length `focal` (pixels, positive), or None: past ±MAX_COORDINATE itself, or making a
    pixel's ray slope (pixel − centre) / focal pass it, which float32 rays cannot hold."""
    if beyond_coordinates([centre]) is not None:
        return f"{centre:.6g} is beyond ±{MAX_COORDINATE:g} (pixel coordinates are 32-bit floats)"
    if max(abs(centre), abs(size - centre)) > MAX_COORDINATE * focal:
        return (f"{centre:.6g} with a focal length of {focal:.6g} px puts ray slopes past "
                f"{MAX_COORDINATE:g} (rays are 32-bit floats)")
    return None


def scaled_norm(values):
    """The Euclidean norm of `values` (finite) without overflow: 1e308 entries square past
    float64, so the norm is taken of the values over their largest magnitude, then scaled."""
    values = np.ravel(np.asarray(values, dtype=np.float64))
    scale = float(np.abs(values).max()) if values.size else 0.0
    return scale * float(np.linalg.norm(values / scale)) if scale > 0 else 0.0


class Fields:
    """Typed access to one JSON object, raising InputError with the full field path."""

    def __init__(self, json_path, prefix, obj):
        self.json_path, self.prefix = json_path, prefix
        if not isinstance(obj, dict):
            self.fail("", "expected a JSON object")
        self.obj = obj

    def name(self, key):
        return f"{self.prefix}.{key}" if self.prefix and key else (self.prefix or key)

    def fail(self, key, problem):
        raise InputError(f"{self.json_path}: {self.name(key)}" if self.name(key) else
                         self.json_path, problem)

    def has(self, key):
        return key in self.obj and self.obj[key] is not None

    def get(self, key, default=None):
        return self.obj.get(key, default)

    def sub(self, key):
        if not self.has(key):
            self.fail(key, "missing")
        return Fields(self.json_path, self.name(key), self.obj[key])

    def number(self, key, default=None, positive=False, nonnegative=False, factor=False):
        """A finite number; factor: one that multiplies or divides float32 pixels or rays, so
        its magnitude must be 0 (where allowed) or within MIN_FACTOR..MAX_FACTOR."""
        if not self.has(key):
            if default is not None:
                return float(default)
            self.fail(key, "missing")
        v = self.obj[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            self.fail(key, f"expected a finite number, got {v!r}")
        if positive and v <= 0:
            self.fail(key, f"expected a positive number, got {v!r}")
        if nonnegative and v < 0:
            self.fail(key, f"expected a non-negative number, got {v!r}")
        if factor:
            self._check_factors(key, [v])
        return float(v)

    def check_coordinates(self, key, values):
        """A position or principal point: any magnitude up to MAX_COORDINATE, 0 included."""
        odd = beyond_coordinates(values)
        if odd is not None:
            self.fail(key, f"{odd:.6g} is beyond ±{MAX_COORDINATE:g} (rays and pixel coordinates "
                           "are 32-bit floats: it would turn them to inf)")

    def _check_factors(self, key, values):
        odd = [v for v in values if v != 0 and not MIN_FACTOR <= abs(v) <= MAX_FACTOR]
        if odd:
            self.fail(key, f"{odd[0]!r} is outside {MIN_FACTOR:g}..{MAX_FACTOR:g} in magnitude "
                           "(photos and rays are 32-bit floats: it would turn them to inf or 0)")

    def integer(self, key, minimum=1, maximum=None):
        v = self.obj.get(key)
        if v is None:
            self.fail(key, "missing")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or v != int(v) or v < minimum or (maximum is not None and v > maximum):
            bounds = f">= {minimum}" if maximum is None else f"in {minimum}..{maximum}"
            self.fail(key, f"expected an integer {bounds}, got {v!r}")
        return int(v)

    def rotation(self, key, matrix):
        """Check that (3, 3) `matrix` (read from `key`) is a rotation: orthonormal, det +1."""
        # entries past 1 fail first: a rotation's never are, and 1e308² would overflow
        if not np.all(np.abs(matrix) <= 1.0 + ROTATION_ATOL) or \
                not np.allclose(matrix.T @ matrix, np.eye(3), atol=ROTATION_ATOL) or \
                abs(np.linalg.det(matrix) - 1.0) > ROTATION_ATOL:
            self.fail(key, "rotation part must be orthonormal with determinant +1 (within "
                           f"{ROTATION_ATOL:g})")
        return matrix

    def choice(self, key, choices, default=None):
        v = self.obj.get(key, default)
        if v is None:
            self.fail(key, f"missing (one of {', '.join(choices)})")
        if v not in choices:
            self.fail(key, f"expected one of {', '.join(choices)}, got {v!r}")
        return v

    def array(self, key, shape, default=None, nonnegative=False, factor=False, coordinate=False):
        """A numeric array of exactly `shape` (nested JSON lists) as float64; factor as for
        number; coordinate: a position (check_coordinates)."""
        if not self.has(key):
            if default is not None:
                return np.array(default, dtype=float)
            self.fail(key, "missing")
        what = f"{shape[0]} numbers" if len(shape) == 1 else "a " + "x".join(map(str, shape)) + \
            " matrix of numbers"
        if holds_bool(self.obj[key]):  # numpy reads true as 1.0: JSON's true is no number
            self.fail(key, f"expected {what}, got true/false")
        try:
            a = np.array(self.obj[key], dtype=float)
        except (TypeError, ValueError):
            self.fail(key, f"expected {what}")
        if a.shape != tuple(shape) or not np.all(np.isfinite(a)):
            self.fail(key, f"expected {what}")
        if nonnegative and np.any(a < 0):
            self.fail(key, f"expected non-negative numbers, got {a.tolist()}")
        if factor:
            self._check_factors(key, a.ravel().tolist())
        if coordinate:
            self.check_coordinates(key, a.ravel().tolist())
        return a

    def path(self, key, folder):
        v = self.obj.get(key)
        if not isinstance(v, str) or not v or "\0" in v:
            self.fail(key, "expected a file name (string, relative to the scene folder)")
        try:
            return (folder / v).resolve()
        except (OSError, RuntimeError, ValueError) as err:
            # a symlink loop, a name too long, a lone surrogate ("\ud800", valid JSON) that no
            # file name encodes
            self.fail(key, f"cannot resolve the path {v!r} ({err})")


def holds_bool(value):
    """Whether `value` is a bool or a (nested) list holding one."""
    if isinstance(value, list):
        return any(holds_bool(v) for v in value)
    return isinstance(value, bool)


class RepeatedKey(ValueError):
    pass


def no_repeats(pairs):
    """json object hook: a dict, or RepeatedKey for a key given twice ("fx": 100, "fx": 5000),
    which json would settle silently by keeping the last."""
    doc = dict(pairs)
    if len(doc) != len(pairs):
        seen = set()
        key = next(k for k, _ in pairs if k in seen or seen.add(k))
        raise RepeatedKey(f"key {key!r} is given twice in one object")
    return doc


def check_finite(value, json_path, where):
    """InputError naming the field (e.g. "camera.width") of the first NaN or +-Infinity.

    Python's json reads NaN, Infinity and 1e999 as floats, and 1 followed by 400 zeros as an int
    no float holds; the contract's JSON has none, and one check over the whole document keeps
    every reader below from meeting them.
    """
    if isinstance(value, float) and not math.isfinite(value):
        raise InputError(f"{json_path}: {where or '(document)'}",
                         f"expected a finite number, got {value!r}")
    if isinstance(value, int) and abs(value) > sys.float_info.max:
        raise InputError(f"{json_path}: {where or '(document)'}",
                         f"expected a finite number, got an integer of {len(str(abs(value)))} "
                         "digits")
    if isinstance(value, dict):
        for key, item in value.items():
            check_finite(item, json_path, f"{where}.{key}" if where else str(key))
    elif isinstance(value, list):
        for k, item in enumerate(value):
            check_finite(item, json_path, f"{where}[{k}]")
