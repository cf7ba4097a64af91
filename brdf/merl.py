"""MERL tables: the isotropic BRDF database layout of Matusik et al. 2003.

A MERL table here is a float64 array of shape (90, 90, 180, 3), indexed [theta_h bin, theta_d bin,
phi_d bin, RGB], holding the BRDF in 1/sr (the file's colour scale already applied) and NaN where
MERL has no data (below the horizon). On disk the layout is MERL's own:

    header   int32 x 3 = (90, 90, 180)
    body     float64, all red, then all green, then all blue; index = phi_d + 180*(theta_d + 90*theta_h)
    value    stored * (1/1500, 1.15/1500, 1.66/1500) = BRDF in 1/sr; negative = no data
"""

import functools
import os

import numpy as np

from flashbrdf.files.atomic import atomic_path
from flashbrdf.files.errors import InputError
from flashbrdf.brdf.rusinkiewicz import cos_in_out

N_THETA_H, N_THETA_D, N_PHI_D = 90, 90, 180
MERL_SHAPE = (N_THETA_H, N_THETA_D, N_PHI_D)
MERL_SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])
MERL_FILE_SIZE = 12 + 8 * 3 * N_THETA_H * N_THETA_D * N_PHI_D  # 34,992,012 bytes
# Largest stored value read (file units): 20 orders of magnitude above the largest in the MERL
# and RGL tables (~7e9), well below where float32 renders overflow (3.4e38)
MAX_STORED_VALUE = 1e30


def theta_h_bin_coordinate(theta_h):
    """MERL's square-root θh binning: the continuous bin coordinate u = 90·sqrt(θh / (π/2)) of
    θh in radians (≥ 0), any shape; bin i spans [i, i + 1). Callers clip and floor as they need.
    The inverse is theta_h_from_bin_coordinate."""
    return np.sqrt(theta_h / (np.pi / 2)) * N_THETA_H


def theta_h_from_bin_coordinate(u, quarter_turn=np.pi / 2):
    """θh = quarter_turn·(u / 90)² of bin coordinates u (any shape): integers give bin edges,
    i + 0.5 bin centres. quarter_turn: π/2 for radians (default), 90.0 for degrees."""
    return quarter_turn * (u / N_THETA_H) ** 2


def theta_h_centres():
    """theta_h bin centres in radians, (90,): (pi/2)((i + 0.5)/90)^2 (square-root spacing)."""
    return theta_h_from_bin_coordinate(np.arange(N_THETA_H) + 0.5)


def theta_d_centres():
    """theta_d bin centres in radians, (90,): (j + 0.5) degrees."""
    return np.deg2rad(np.arange(N_THETA_D) + 0.5)


def phi_d_centres():
    """phi_d bin centres in radians, (180,): (k + 0.5) degrees over [0, pi)."""
    return np.deg2rad(np.arange(N_PHI_D) + 0.5)


@functools.lru_cache(maxsize=1)
def _valid_mask():
    cos_i, cos_o = cos_in_out(*np.meshgrid(theta_h_centres(), theta_d_centres(), phi_d_centres(),
                                           indexing="ij"))
    mask = (cos_i > 0) & (cos_o > 0)
    mask.setflags(write=False)
    return mask


def merl_valid_mask():
    """(90, 90, 180) bool: bins whose centre has both directions above the horizon.

    This is where the MERL database (and the NBRDF proxy) stores data; elsewhere it is negative.
    """
    return _valid_mask()


def _check_size(path):
    """InputError naming path unless it is a MERL file's size (OSError passes through)."""
    size = os.path.getsize(path)
    if size != MERL_FILE_SIZE:
        raise InputError(path, f"not a MERL table: {size} bytes, expected {MERL_FILE_SIZE}")


def _check_header(path, header):
    """InputError naming path unless header (3,) int is MERL's (90, 90, 180)."""
    if tuple(header) != MERL_SHAPE:
        raise InputError(path, f"wrong MERL header {tuple(int(h) for h in header)}, "
                               f"expected {MERL_SHAPE}")


def _read_raw(path):
    """The validated body of a MERL file as stored: (3, 90*90*180) float64, file units."""
    path = os.fspath(path)
    try:
        _check_size(path)
        with open(path, "rb") as f:
            header = np.fromfile(f, dtype="<i4", count=3)
            body = np.fromfile(f, dtype="<f8")
    except OSError as err:
        raise InputError(path, f"cannot read: {err.strerror or err}") from None
    _check_header(path, header)
    if not np.all(np.isfinite(body)):
        bad = int(np.count_nonzero(~np.isfinite(body)))
        raise InputError(path, f"{bad} NaN/Inf values in the table")
    top = body.max()
    if top < 0:
        raise InputError(path, "the table has no valid bin (every value is negative: no data)")
    if top > MAX_STORED_VALUE:
        raise InputError(path, f"value {top:.3g} is not a BRDF (stored values above "
                               f"{MAX_STORED_VALUE:g} overflow the renders)")
    return body.reshape(3, -1)


def read_merl(path):
    """Read a MERL `.binary` file.

    Returns a (90, 90, 180, 3) float64 table in 1/sr with NaN where the file has no data
    (negative values). Raises InputError naming the file for a wrong size, a wrong header,
    NaN/Inf values, no valid value or a value above MAX_STORED_VALUE.
    """
    raw = _read_raw(path).reshape(3, *MERL_SHAPE)
    table = np.moveaxis(raw, 0, -1) * MERL_SCALE
    table[table < 0] = np.nan
    return table


def read_theta_d_row(path, theta_d_bin=0):
    """ρ (90, 180, 3) in 1/sr of one θd row of a MERL file (NaN where no data), read as its 270
    runs of 180 values (a 90th of the file; the kernel told not to read ahead); the size and
    header are checked."""
    path = os.fspath(path)
    run = N_PHI_D * 8
    try:
        _check_size(path)
        fd = os.open(path, os.O_RDONLY)
        try:
            if hasattr(os, "posix_fadvise"):
                os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_RANDOM)
            _check_header(path, np.frombuffer(os.pread(fd, 12, 0), dtype="<i4"))
            stride = N_THETA_D * run
            channel = N_THETA_H * stride
            data = b"".join(os.pread(fd, run, 12 + c * channel + h * stride + theta_d_bin * run)
                            for c in range(3) for h in range(N_THETA_H))
        finally:
            os.close(fd)
    except OSError as err:
        raise InputError(path, f"cannot read: {err.strerror or err}") from None
    row = np.frombuffer(data, dtype="<f8").reshape(3, N_THETA_H, N_PHI_D)
    row = np.moveaxis(row, 0, -1) * MERL_SCALE
    row[~(row >= 0)] = np.nan
    return row


def read_merl_bins(path, flat_index, dtype=np.float64):
    """Read only some bins of a MERL `.binary` file, checked like read_merl.

    flat_index: (n,) int indices into the (90, 90, 180) grid, i.e. phi_d + 180*(theta_d + 90*theta_h).
    Returns (n, 3) ρ in 1/sr of `dtype`, NaN where the file has no data. The array is a transposed
    (3, n) buffer, so each channel column is contiguous (per-channel maps over 1.1 M bins stay fast).
    """
    values = np.take(_read_raw(path), flat_index, axis=1).astype(dtype, copy=False)
    values *= MERL_SCALE.astype(dtype)[:, None]
    values[values < 0] = np.nan
    return values.T


def write_merl(path, table, no_data=None):
    """Write a (90, 90, 180, 3) table in 1/sr as a MERL `.binary` file, atomically.

    NaN, Inf or negative values are written as no data (-1 in file units), and so are the bins
    of no_data ((90, 90, 180) bool) when given. `table` may be a broadcast view (a 2D table
    across phi_d): the file is built channel by channel, in place. The file is exactly
    34,992,012 bytes.
    """
    table = np.asarray(table)
    if table.shape != MERL_SHAPE + (3,):
        raise ValueError(f"MERL table must be {MERL_SHAPE + (3,)}, got {table.shape}")
    raw = np.empty((3,) + MERL_SHAPE, dtype="<f8")
    for c in range(3):
        np.divide(table[..., c], MERL_SCALE[c], out=raw[c])
    with np.errstate(invalid="ignore"):
        missing = ~(raw >= 0)   # NaN too
    missing |= np.isinf(raw)
    if no_data is not None:
        missing |= no_data
    raw[missing] = -1.0
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.array(MERL_SHAPE, dtype="<i4").tofile(f)
            raw.tofile(f)


def list_merl(folder):
    """Sorted [(name, path)] of the `*.binary` files in `folder`; reads no table.

    Raises InputError if the folder does not exist or holds no `.binary` file.
    """
    folder = os.fspath(folder)
    if not os.path.isdir(folder):
        raise InputError(folder, "not a folder")
    names = sorted(f for f in os.listdir(folder) if f.endswith(".binary"))
    if not names:
        raise InputError(folder, "no MERL .binary files in this folder")
    return [(n[: -len(".binary")], os.path.join(folder, n)) for n in names]


def list_merl_dirs(folders, options="the --merl-dir folders", why=""):
    """{name: path} of the `*.binary` files of every folder in `folders` (a path or a list of
    paths), in folder order then name order; reads no table.

    Material names must be unique across folders, since models and `infer --merl-dir` match tables
    by name: InputError naming both files otherwise. An empty or missing folder is an InputError
    naming it (list_merl). options: what the folders are on the command line, and why: the
    reason names must differ, for the messages.
    """
    if isinstance(folders, (str, os.PathLike)):
        folders = [folders]
    found, seen = {}, {}
    for folder in folders:
        real = os.path.realpath(folder)
        if real in seen:
            raise InputError(folder, f"is given twice (also as {seen[real]}); give each of "
                                     f"{options} once")
        seen[real] = folder
        for name, path in list_merl(folder):
            if name in found:
                raise InputError(path, f"material name {name!r} is also {found[name]}; names must "
                                       f"be unique across {options}{why}")
            found[name] = path
    return found
