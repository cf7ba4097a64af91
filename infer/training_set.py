"""The training materials every method fits on: names, flash slices, 2D tables, and 3D tables read
one at a time (MERL files or stored rows). Values in 1/sr, NaN where MERL has no data.
"""

import hashlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np

from flashbrdf.brdf import merl, views
from flashbrdf.brdf.bins import valid_bins_3d, valid_flat_3d, valid_mask_2d
from flashbrdf.files.errors import InputError
from flashbrdf.files.threads import thread_budget


def default_threads():
    """Threads for per-table work: files.threads.thread_budget, at most 4 unless set."""
    return thread_budget(4)


def _read_views(path, keep_3d, bins_3d, fill=True):
    """(flash slice (90, 3), 2D table (90, 90, 3), valid 3D bins (n, 3) float32 or None, the
    (90, 90) bool mask of the 2D bins that held no data) of one MERL file, its no-data bins
    filled (fill_missing_2d) or, for a table that is only scored (fill=False), left NaN."""
    table = merl.read_merl(path)
    flash_slice = views.flash_slice(table)[0]
    views.check_flash_slice(flash_slice, path)   # a table with no θd = 0 row is refused, not filled
    raw_2d = views.table_2d(table)
    holes = ~np.isfinite(raw_2d).all(axis=-1) & valid_mask_2d()
    if not fill:
        return flash_slice, raw_2d, table[bins_3d].astype(np.float32) if keep_3d else None, holes
    table_2d, _ = fill_missing_2d(raw_2d)
    rows = fill_missing_3d(table[bins_3d], table_2d).astype(np.float32) if keep_3d else None
    flash_slice = np.where(np.isfinite(flash_slice), flash_slice, table_2d[:, 0])
    return flash_slice, table_2d, rows, holes


_FILL_FLOOR = 1e-6  # 1/sr: ln(ρ + floor) is interpolated, so a black neighbour stays finite


def fill_missing_2d(table_2d):
    """(table (90, 90, 3) with its no-data bins (NaN inside brdf.bins.valid_mask_2d, MERL's
    negative values in every φd) filled, how many (θh, θd) bins were filled).

    A training table is one row of every method's data matrix: one hole would void a PCA basis,
    a Gram matrix or a GP's features for every prediction. Each hole gets ln(ρ + 1e-6)
    interpolated linearly along θh within its θd column (the nearest value past either end), and
    where a whole column is empty, along θd. MERL's own tables have none."""
    valid = valid_mask_2d()
    holes = valid[..., None] & ~np.isfinite(table_2d)
    if not holes.any():
        return table_2d, 0
    log = np.log(np.maximum(table_2d, 0.0) + _FILL_FLOOR)
    log[~valid] = np.nan
    for axis in (0, 1):  # along θh in each column, then along θd for what is left
        moved = np.moveaxis(log, axis, 0)   # a view: writes land in `log`
        for j in range(moved.shape[1]):
            for c in range(3):
                line, inside = moved[:, j, c], np.moveaxis(valid, axis, 0)[:, j]
                known = np.isfinite(line)
                gap = inside & ~known
                if gap.any() and known.any():
                    line[gap] = np.interp(np.flatnonzero(gap), np.flatnonzero(known), line[known])
    filled = np.where(holes, np.exp(log) - _FILL_FLOOR, table_2d)
    return np.maximum(filled, 0.0, where=holes, out=filled), int(holes.any(axis=2).sum())


def fill_missing_3d(rows, table_2d):
    """Valid 3D bins (n, 3) with their no-data values (NaN) set to the (filled) 2D table's value
    at their (θh, θd): the table's φd mean stands in for the φd bins it lacks."""
    missing = ~np.isfinite(rows)
    if not missing.any():
        return rows
    ih, jd, _ = valid_bins_3d()
    return np.where(missing, table_2d[ih, jd], rows)


# Fewest training tables (`train` holds a fifth of them out to validate; the GPs need a spread).
MIN_TRAINING_TABLES = 4


def table_key(table_2d):
    """A table's identity as `train` fits it: the sha256 of its (filled) 2D view in float32, as
    MODEL.npz stores it (tables 1e-9 apart are one)."""
    return hashlib.sha256(np.ascontiguousarray(table_2d, np.float32).tobytes()).hexdigest()


def check_unseen(test, training):
    """InputError naming a table of the TrainingSet `test` that holds the same table as one of
    `training` (under another name: names are checked by brdf.merl.list_merl_dirs), and both
    files: a score on it would be a score on training data. test may be unfilled (fill=False):
    its tables are compared as training fills them."""
    trained = {table_key(t): p for p, t in zip(training.paths, training.tables_2d)}
    for path, table in zip(test.paths, test.tables_2d):
        original = trained.get(table_key(fill_missing_2d(table)[0] if not test.fill else table))
        if original is not None:
            raise InputError(path, f"holds the same table as the training table {original}: a "
                                   "test table is never also a training table")


def check_distinct(paths, tables_2d):
    """InputError when fewer than MIN_TRAINING_TABLES of the training tables differ (2D view, bit
    for bit in float32, as MODEL.npz stores and train fits them: tables 1e-9 apart are one),
    naming the first copy; for a training set only (a test set may hold copies).
    Copies of a table (one material under two names, links to one file) are allowed as
    near-duplicates are: the jittered Cholesky takes a repeated row. But five copies of one table
    leave nothing to learn (the GP covariances went singular: a LinAlgError traceback)."""
    if len(paths) < MIN_TRAINING_TABLES:
        return  # too few in any case: check_training_size names the folder
    seen, first_copy = {}, None
    for path, table in zip(paths, tables_2d):
        key = table_key(table)
        if key in seen and first_copy is None:
            first_copy = (path, seen[key])
        seen.setdefault(key, path)
    if len(seen) < MIN_TRAINING_TABLES:
        path, original = first_copy
        raise InputError(path, f"holds the same table as {original}: only {len(seen)} of the "
                               f"{len(paths)} tables differ, and training needs "
                               f"{MIN_TRAINING_TABLES} different ones")


SAME_TABLE_LN = 0.01       # a table whose θd = 0 slice is off by more (median |Δ ln ρ|) differs
OTHER_MATERIAL_LN = np.log(2.0)  # off by more than a factor 2: another material


def check_3d_tables(training):
    """Compare each table at training.paths (a --merl-dir's, matched by name) with the model's
    stored flash slice, reading only its θd = 0 row. Records the tables off by a median |Δ ln ρ|
    over SAME_TABLE_LN in training.differing_3d (the 3D prediction mixes the files given, not the
    model's tables: real MERL files beside a model trained on proxies); InputError naming the
    file when one is off by more than a factor 2 (another material under the model's name, a
    3D prediction of no meaning)."""
    training.differing_3d = []
    for name, path, stored in zip(training.names, training.paths, training.slices):
        if path is None:
            continue
        given = views.flash_slice(merl.read_theta_d_row(path)[:, None])[0]
        ok = np.isfinite(given) & np.isfinite(stored)
        if not ok.any():
            continue
        off = float(np.median(np.abs(np.log((given[ok] + 1e-4) / (stored[ok] + 1e-4)))))
        if off > OTHER_MATERIAL_LN:
            raise InputError(path, f"is not the table {name!r} the model was trained on: its "
                                   f"θd = 0 slice is off by a median factor {np.exp(off):.3g}; "
                                   "give --merl-dir the folder the model was trained from")
        if off > SAME_TABLE_LN:
            training.differing_3d.append((name, off))


@dataclass
class TrainingSet:
    """Training materials: names (N,), flash slices (N, 90, 3), 2D tables (N, 90, 90, 3), in 1/sr.

    fitted_pca: see below.
    3D tables are never all held in memory: `table_3d_valid(i)` reads one at a time, either from
    `paths` (MERL .binary files) or from `valid_3d` (N, n_valid, 3) stored rows (array or memmap).
    """
    names: list
    slices: np.ndarray
    tables_2d: np.ndarray
    paths: list = None
    valid_3d: np.ndarray = field(default=None, repr=False)
    # a PCA fitted on exactly these tables when the model was trained (PCA.state(), read from
    # MODEL.npz): PCA.fit with the same hyperparameters restores it instead of refitting (the
    # median and Gram matrix over every table, ~45 ms of `infer`'s ~1 s). A subset does not
    # carry it.
    fitted_pca: dict = field(default=None, repr=False)
    # {MERL file: how many of its (θh, θd) bins held no data and were filled (fill_missing_2d)}
    filled_bins: dict = field(default_factory=dict)
    fill: bool = True  # table_3d_valid fills no-data bins too (False: tables only scored)
    # (N, 90, 90) bool: the 2D bins that held no data (filled for training, not scored), or None
    holes_2d: np.ndarray = field(default=None, repr=False)
    # [(name, median |Δ ln ρ| of its θd = 0 slice)]: `paths` tables that are not quite the ones
    # the model was trained on (check_3d_tables)
    differing_3d: list = field(default_factory=list)
    checked_3d: bool = field(default=False, repr=False)

    def __len__(self):
        return len(self.names)

    @classmethod
    def from_merl_dir(cls, folder, names=None, keep_3d=False, fill=True):
        """Read the MERL tables of `folder` (all, or those in `names`, in that order).
        keep_3d: also hold their valid 3D bins as float32 rows (N × 1.1 M × 3 × 4 B).
        fill: fill their no-data bins (fill_missing_2d), as training needs; False for tables
        that are only scored, whose holes the metrics skip."""
        found = dict(merl.list_merl(folder))
        if not found:
            raise InputError(folder, "no .binary MERL tables in this folder")
        names = list(found) if names is None else list(names)
        missing = [n for n in names if n not in found]
        if missing:
            raise InputError(folder, f"missing MERL tables: {', '.join(missing[:5])}")
        # numpy's reads and reductions release the GIL: threads read tables side by side, and
        # each table's arithmetic is the same as read alone (same result for any thread count)
        bins_3d = valid_bins_3d() if keep_3d else None
        with ThreadPoolExecutor(min(default_threads(), len(names))) as pool:
            read = list(pool.map(lambda n: _read_views(found[n], keep_3d, bins_3d, fill), names))
        slices, tables, rows, holes = ([r[k] for r in read] for k in range(4))
        counts = [int(h.sum()) if fill else 0 for h in holes]
        return cls(names, np.array(slices), np.array(tables), [found[n] for n in names],
                   np.array(rows) if keep_3d else None,
                   filled_bins={str(found[n]): c for n, c in zip(names, counts) if c}, fill=fill,
                   holes_2d=np.array(holes) if any(h.any() for h in holes) else None)

    @classmethod
    def from_merl_dirs(cls, folders, keep_3d=False):
        """Every MERL table of every folder in `folders` (a list of paths), folder by folder, in
        one set. Names must be unique across folders and no folder may be empty (InputError,
        checked before any table is read: brdf.merl.list_merl_dirs)."""
        merl.list_merl_dirs(folders)
        parts = [cls.from_merl_dir(f, keep_3d=keep_3d) for f in folders]
        check_distinct([q for p in parts for q in p.paths],
                       [t for p in parts for t in p.tables_2d])
        return cls(names=[n for p in parts for n in p.names],
                   slices=np.concatenate([p.slices for p in parts]),
                   tables_2d=np.concatenate([p.tables_2d for p in parts]),
                   paths=[q for p in parts for q in p.paths],
                   valid_3d=np.concatenate([p.valid_3d for p in parts]) if keep_3d else None,
                   filled_bins={k: v for p in parts for k, v in p.filled_bins.items()},
                   holes_2d=None if all(p.holes_2d is None for p in parts) else np.concatenate(
                       [np.zeros((len(p), 90, 90), bool) if p.holes_2d is None else p.holes_2d
                        for p in parts]))

    def check_3d_files(self):
        """check_3d_tables once, before the first 3D prediction reads the tables at `paths`
        (a 2D prediction never reads them, so it is never refused over them)."""
        if not self.checked_3d and self.paths is not None and self.valid_3d is None:
            check_3d_tables(self)
            self.checked_3d = True

    def as_stored(self):
        """This set with its 2D tables rounded to float32, as MODEL.npz stores them: what a
        model is fitted on, so that a load rebuilds exactly the training rows it was fitted on
        (near-duplicate tables differ by little more than float32's rounding)."""
        return replace(self, tables_2d=np.asarray(self.tables_2d, np.float32).astype(np.float64),
                       fitted_pca=None)

    def without_stored_3d(self):
        """This set without its stored 3D rows (valid_3d: GBs): what a 2D fit needs, and what
        a process pool can be handed cheaply."""
        return self if self.valid_3d is None else replace(self, valid_3d=None)

    def subset(self, index):
        index = list(index)
        return TrainingSet([self.names[i] for i in index], self.slices[index], self.tables_2d[index],
                           None if self.paths is None else [self.paths[i] for i in index],
                           None if self.valid_3d is None else self.valid_3d[index],
                           fill=self.fill,
                           holes_2d=None if self.holes_2d is None else self.holes_2d[index])

    def scored_table(self, i):
        """Material i's 2D table as a metric scores it: the bins that held no data NaN (the
        metrics skip them), not the values training filled them with."""
        if self.holes_2d is None or not self.holes_2d[i].any():
            return self.tables_2d[i]
        return np.where(self.holes_2d[i][..., None], np.nan, self.tables_2d[i])

    @property
    def missing_3d(self):
        """Names of the materials whose 3D table is not at hand (their 2D table stands in)."""
        if self.valid_3d is not None or self.paths is None:
            return []
        return [n for n, p in zip(self.names, self.paths) if p is None]

    def has_3d(self):
        return self.valid_3d is not None or self.paths is not None

    def table_3d_valid(self, i, dtype=np.float64):
        """ρ on the valid 3D bins of material i, (n_valid, 3) of `dtype`."""
        if self.valid_3d is not None:
            return np.asarray(self.valid_3d[i], dtype=dtype)
        if self.paths is None:
            raise InputError("--merl-dir", "3D prediction needs the training tables: give --merl-dir "
                             "or train with --views 1d,2d,3d")
        if self.paths[i] is None:  # its 3D table was not found: the 2D table across phi_d
            ih, jd, _ = valid_bins_3d()
            return np.nan_to_num(np.asarray(self.tables_2d[i][ih, jd], dtype=dtype))
        rows = merl.read_merl_bins(self.paths[i], valid_flat_3d(), dtype)
        if not self.fill:
            return rows
        return fill_missing_3d(rows, self.tables_2d[i]).astype(dtype, copy=False)
