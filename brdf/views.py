"""The three views of a BRDF used by the paper: the 1D flash slice, the 2D and the 3D table.

- 1D: rho(theta_h) at theta_d bin 0, mean over the valid phi_d bins: (90, 3), plus a count n.
- 2D: rho(theta_h, theta_d), mean over the valid phi_d bins: (90, 90, 3).
- 3D: the full MERL table (90, 90, 180, 3).
NaN marks an empty bin in every view; `np.isfinite(view[..., 0])` is its validity mask.
Also reads and writes the contract's `slice.csv`.
"""

import csv
import io
import os

import numpy as np

from flashbrdf.files.atomic import write_text
from flashbrdf.files.errors import InputError
from flashbrdf.brdf.merl import N_THETA_H, merl_valid_mask, theta_h_centres, theta_h_from_bin_coordinate

SLICE_HEADER = ["theta_h_deg", "r", "g", "b", "n"]
# Largest slice value read (1/sr): 17 orders above the largest in MERL (~3e3 at theta_h = 0);
# a prediction from a larger one would not fit in a MERL table (brdf.merl.MAX_STORED_VALUE)
MAX_SLICE_VALUE = 1e20


def _nanmean(values, axis):
    """np.nanmean (the same sums, so the same bits) with all-NaN bins left NaN on purpose, and no
    RuntimeWarning: no warnings.catch_warnings, which is not thread-safe (tables are read by
    threads, infer.training_set)."""
    values = np.asarray(values, dtype=np.float64)
    missing = np.isnan(values)
    total = np.sum(np.where(missing, 0.0, values), axis=axis)
    count = np.sum(~missing, axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return total / count


def flash_slice(merl_table):
    """The theta_d = 0 slice: (rho (90, 3) in 1/sr with NaN where empty, n (90,) int).

    rho is the mean over the valid phi_d bins of theta_d bin 0; n counts those bins.
    """
    first = np.asarray(merl_table)[:, 0]
    n = np.count_nonzero(np.all(np.isfinite(first), axis=-1), axis=1)
    return _nanmean(first, axis=1), n


def check_flash_slice(rho, where):
    """InputError naming `where` when the flash slice rho (90, 3) (flash_slice) holds no bin
    with all three channels: the table has no data at theta_d = 0, where every method starts (a
    slice.csv row needs R, G and B); or a value above MAX_SLICE_VALUE, which read_slice_csv
    refuses (merl-slice wrote such a slice with exit 0)."""
    if not np.isfinite(rho).any():
        raise InputError(where, "has no value at theta_d = 0 (every bin of its first theta_d row "
                                "is negative: no data): its flash slice is empty")
    if not np.isfinite(rho).all(axis=1).any():
        raise InputError(where, "has no theta_d = 0 bin with data in all three channels (a "
                                "channel is negative, no data, throughout): its flash slice is "
                                "empty")
    top = np.nanmax(rho)
    if top > MAX_SLICE_VALUE:  # a slice.csv holding it is refused by every reader
        raise InputError(where, f"its flash slice reaches {top:.3g} 1/sr, above the "
                                f"{MAX_SLICE_VALUE:g} a slice holds: not a BRDF (check the "
                                "table's units)")


def table_2d(merl_table):
    """rho(theta_h, theta_d): (90, 90, 3), the mean over the valid phi_d bins, NaN where none."""
    return _nanmean(np.asarray(merl_table), axis=2)


def table_in_plane(merl_table):
    """rho(theta_h, theta_d) (90, 90, 3) in the plane of incidence, where phi_d = 0 (folded into
    [0, pi)): the mean of phi_d bins 0 and 179, either side of it, NaN where neither has data."""
    sides = np.asarray(merl_table, dtype=float)[:, :, [0, -1]]
    return _nanmean(sides, axis=2)


def table_2d_view(table):
    """rho(theta_h, theta_d) (90, 90, 3) of a 2D table (as is) or a 3D one (table_2d)."""
    table = np.asarray(table, dtype=float)
    return table_2d(table) if table.ndim == 4 else table


def variance_2d_view(variance):
    """A prediction's variance beside its 2D table: (90, 90) or (90, 90, 3) as is, a 3D
    (phi_d-resolved) one averaged over phi_d like the table; None when there is none, or its
    shape is not a 2D table's."""
    if variance is None:
        return None
    variance = np.asarray(variance, dtype=float)
    if variance.ndim == 4:
        variance = _nanmean(variance, axis=2)
    return variance if variance.shape[:2] == (90, 90) and variance.ndim in (2, 3) else None


def table_3d_from_2d(table_2d):
    """A (90, 90, 180, 3) table copying `table_2d` across phi_d, NaN where MERL has no data."""
    table = np.repeat(np.asarray(table_2d, dtype=np.float64)[:, :, None, :], 180, axis=2)
    table[~merl_valid_mask()] = np.nan
    return table


def slice_coverage(filled):
    """Which θh bins of a 1D slice hold data. filled: (90,) bool with at least one True.

    Returns a dict of ints and degrees: bins_filled (count), first_bin, last_bin, empty_bins
    (list of all empty bin indices, also those outside [first_bin, last_bin]), gaps (empty bins
    inside that range), theta_h_deg_filled ([centre of first_bin, centre of last_bin]) and
    theta_h_deg_range ([lower edge of first_bin, upper edge of last_bin])."""
    filled = np.asarray(filled, dtype=bool)
    index = np.flatnonzero(filled)
    first, last = int(index[0]), int(index[-1])
    centres = np.degrees(theta_h_centres())
    edges = theta_h_from_bin_coordinate(np.arange(N_THETA_H + 1), 90.0)  # in degrees
    return {"bins_filled": int(len(index)), "first_bin": first, "last_bin": last,
            "empty_bins": [int(i) for i in np.flatnonzero(~filled)],
            "gaps": int((~filled[first:last + 1]).sum()),
            "theta_h_deg_filled": [float(centres[first]), float(centres[last])],
            "theta_h_deg_range": [float(edges[first]), float(edges[last + 1])]}


def write_slice_csv(path, rho, n, comments=()):
    """Write the contract's slice.csv atomically.

    rho: (90, 3) in 1/sr, NaN (or any non-finite) where the bin has no sample; n: (90,) counts.
    comments: lines written first, each prefixed with '# '.
    """
    rho = np.asarray(rho, dtype=np.float64)
    n = np.asarray(n)
    if rho.shape != (N_THETA_H, 3) or n.shape != (N_THETA_H,):
        raise ValueError(f"slice must be (90, 3) with (90,) counts, got {rho.shape}, {n.shape}")
    out = io.StringIO()
    for line in comments:
        out.write("# " + str(line).replace("\n", " ") + "\n")
    out.write(",".join(SLICE_HEADER) + "\n")
    for theta, row, count in zip(np.degrees(theta_h_centres()), rho, n):
        values = ",".join(repr(float(v)) for v in row) if np.all(np.isfinite(row)) else ",,"
        out.write(f"{float(theta)!r},{values},{int(count)}\n")
    write_text(path, out.getvalue())


def _half_last_digit(text):
    """Half a unit of the last digit printed in a plain decimal ("0.03" -> 0.005, "1" -> 0.5;
    0 for exponent notation, which says nothing of its rounding)."""
    text = text.strip()
    if "e" in text.lower():
        return 0.0
    decimals = len(text.partition(".")[2])
    return 0.5 * 10.0 ** -decimals


LEVEL_COMMENT = "level: "  # a slice.csv comment flashbrdf writes: how its absolute level is known


def slice_level(path):
    """BRDF.json's "level" from a slice.csv's "# level: ..." comment (extract and merl-slice
    write one): {"absolute": True | False | None, "note": text}; absolute None when the file
    states none (a slice made elsewhere). Reads comments only: read_slice_csv checks the file."""
    try:
        with open(os.fspath(path), encoding="utf-8-sig") as f:
            for line in f:
                text = line.strip().lstrip("#").strip()
                if line.lstrip().startswith("#") and text.startswith(LEVEL_COMMENT):
                    note = text[len(LEVEL_COMMENT):]
                    absolute = (True if note.startswith("absolute") else
                                False if note.startswith("relative") else None)
                    return {"absolute": absolute, "note": note}
    except (OSError, UnicodeDecodeError):
        pass
    return {"absolute": None, "note": "the slice file states no level"}


def read_slice_csv(path):
    """Read a contract slice.csv: (rho (90, 3) in 1/sr with NaN where empty, n (90,) int).

    Raises InputError naming the file and the line for anything that is not the contract's format.
    """
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8-sig") as f:  # a byte-order mark (spreadsheets) is no text
            lines = [(k + 1, line) for k, line in enumerate(f)
                     if line.strip() and not line.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(path, f"cannot read: {getattr(err, 'strerror', None) or err}") from None
    if not lines:
        raise InputError(path, "empty slice file")
    header = [h.strip() for h in lines[0][1].strip().split(",")]
    if header != SLICE_HEADER:
        raise InputError(path, f"line {lines[0][0]}: header must be {','.join(SLICE_HEADER)}")
    rows = lines[1:]
    if len(rows) != N_THETA_H:
        raise InputError(path, f"expected {N_THETA_H} data rows, found {len(rows)}")
    centres = np.degrees(theta_h_centres())
    # A centre printed with few decimals is still that centre (0.00 for bin 0's 0.0027778): allow
    # half the gap to the nearest other centre, or half a unit of the last printed digit, whichever
    # is larger (rows are in bin order, so this only checks the binning is the contract's).
    gaps = np.diff(centres)
    slack = 0.5 * np.minimum(np.r_[np.inf, gaps], np.r_[gaps, np.inf])
    rho = np.full((N_THETA_H, 3), np.nan)
    n = np.zeros(N_THETA_H, dtype=np.int64)
    for i, (lineno, line) in enumerate(rows):
        fields = next(csv.reader([line.strip()]))
        where = f"line {lineno}"
        if len(fields) != 5:
            raise InputError(path, f"{where}: expected 5 fields, found {len(fields)}")
        try:
            theta = float(fields[0])
            count = float(fields[4]) if fields[4].strip() else 0.0  # "180.0" is 180 samples
            values = [float(v) if v.strip() else np.nan for v in fields[1:4]]
        except ValueError:
            raise InputError(path, f"{where}: not a number") from None
        if not count.is_integer():
            raise InputError(path, f"{where}: sample count {fields[4].strip()[:20]} is not a "
                                   "whole number")
        try:
            n[i] = int(count)
        except OverflowError:  # n beyond int64
            raise InputError(path, f"{where}: sample count {fields[4].strip()[:20]} is too "
                                   "large") from None
        if n[i] < 0:
            raise InputError(path, f"{where}: negative sample count")
        if not abs(theta - centres[i]) <= max(slack[i], _half_last_digit(fields[0])):
            raise InputError(path, f"{where}: theta_h_deg {theta} is not bin {i}'s centre "
                                   f"{centres[i]:.6f}")
        present = [bool(v.strip()) for v in fields[1:4]]
        if any(present) and not all(present):
            raise InputError(path, f"{where}: r, g, b must be all given or all empty")
        if any(present):
            if not all(np.isfinite(values)):
                raise InputError(path, f"{where}: NaN or Inf value")
            if min(values) < 0:
                raise InputError(path, f"{where}: negative BRDF value")
            if max(values) > MAX_SLICE_VALUE:
                raise InputError(path, f"{where}: value {max(values):.3g} is not a BRDF (above "
                                       f"{MAX_SLICE_VALUE:g} 1/sr)")
            rho[i] = values
    if not np.any(np.isfinite(rho[:, 0])):
        raise InputError(path, "the slice has no sample in any bin")
    return rho, n
