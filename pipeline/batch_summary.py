"""The batch's summary: OUT_DIR/summary.csv and summary.md, one row per capture (the contract's
`capture`, `status`, `reason`, per-method ΔE-log, `seconds`; then ours), index.html linking each
capture's report.html (pipeline.report_index), and the rows themselves."""

import csv
import io
from pathlib import Path

from flashbrdf.files.atomic import write_text
from flashbrdf.pipeline.report_index import INDEX_HEAD, INDEX_NAME, write_batch_index

# The contract's column order: `capture`, `status`, `reason`, per-method ΔE-log, seconds, then
# ours (cpu_seconds, worker).
SUMMARY_FIELDS = ("capture", "status", "reason", "seconds", "cpu_seconds", "worker")
SUMMARY_LEAD, SUMMARY_TAIL = SUMMARY_FIELDS[:3], SUMMARY_FIELDS[3:]  # before / after the ΔE-log
SUMMARY_TITLE = "# flashbrdf batch summary"
# How a summary that a batch wrote starts: summary.csv without ΔE-log columns (or as batches
# before the contract's column order wrote it), or with them.
SUMMARY_HEADS = {"summary.csv": (",".join(SUMMARY_FIELDS).encode(),
                                 (",".join(SUMMARY_LEAD) + ",delta_e_log ").encode()),
                 "summary.md": (SUMMARY_TITLE.encode(),), INDEX_NAME: (INDEX_HEAD.encode(),)}


def row_from_report(name, report, seconds, cpu_seconds, worker):
    """The summary row of one finished capture from its report.json (dict). seconds: wall;
    cpu_seconds: the worker process's CPU time (user + system) over the capture, which a loaded
    machine does not inflate as it does the wall time."""
    row = {"capture": name, "status": "ok", "reason": "", "seconds": round(seconds, 3),
           "cpu_seconds": round(cpu_seconds, 3), "worker": worker, "delta_e_log": {}}
    for method, s in report.get("summary", {}).items():
        row["delta_e_log"][method] = s.get("delta_e_log_mean", {}).get("mean")
    for r in report.get("references", []):
        row["delta_e_log"][f"{r['method']}/{r['photo']}"] = r.get("delta_e_log_mean")
    return row


def failed_row(name, reason, seconds=None, worker=""):
    """The summary row of a failed capture; `reason` is cut to its first line."""
    lines = str(reason).strip().splitlines()
    return {"capture": name, "status": "failed", "reason": lines[0] if lines else "failed",
            "seconds": None if seconds is None else round(seconds, 3), "cpu_seconds": None,
            "worker": worker,
            "delta_e_log": {}}


def _columns(rows, methods=()):
    """ΔE-log columns: (each method's mean, `methods` first then any other seen, in the
    contract's place before `seconds`; each method/photo, after our own fields)."""
    keys = list(dict.fromkeys([*methods, *(k for r in rows for k in r["delta_e_log"])]))
    return [k for k in keys if "/" not in k], [k for k in keys if "/" in k]


def _cell(value):
    if value is None:
        return ""
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def _field(row, name):
    return "" if row.get(name) is None else row[name]


def write_summary(out_dir, rows, header_lines=(), methods=()):
    """OUT_DIR/summary.csv and summary.md, one row per capture (atomic writes). Columns: the
    contract's `capture`, `status`, `reason`, per-method ΔE-log (every one of `methods`, even when
    no capture succeeded), `seconds`; then ours: `cpu_seconds`, `worker`, per-photo ΔE-log."""
    per_method, per_photo = _columns(rows, methods)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(list(SUMMARY_LEAD) + [f"delta_e_log {c}" for c in per_method]
                    + list(SUMMARY_TAIL) + [f"delta_e_log {c}" for c in per_photo])

    def values(r, columns):
        return [repr(r["delta_e_log"][c]) if r["delta_e_log"].get(c) is not None else ""
                for c in columns]

    for r in rows:
        writer.writerow([_field(r, f) for f in SUMMARY_LEAD] + values(r, per_method)
                        + [_field(r, f) for f in SUMMARY_TAIL] + values(r, per_photo))
    write_text(Path(out_dir) / "summary.csv", buffer.getvalue())
    head = (list(SUMMARY_LEAD) + [f"ΔE-log {c}" for c in per_method] + list(SUMMARY_TAIL)
            + [f"ΔE-log {c}" for c in per_photo])
    lines = [SUMMARY_TITLE, "", *header_lines, "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [_cell(r.get(f)).replace("|", "\\|") for f in SUMMARY_LEAD]
        cells += [_cell(r["delta_e_log"].get(c)) for c in per_method]
        cells += [_cell(r.get(f)).replace("|", "\\|") for f in SUMMARY_TAIL]
        cells += [_cell(r["delta_e_log"].get(c)) for c in per_photo]
        lines.append("| " + " | ".join(cells) + " |")
    write_text(Path(out_dir) / "summary.md", "\n".join(lines) + "\n")
    write_batch_index(out_dir, rows, per_method, header_lines)
