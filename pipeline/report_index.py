"""OUT_DIR/index.html of `flashbrdf batch`: one row per capture, linking its report.html.

Static HTML with the report pages' stylesheet inlined: no script, nothing loaded from outside
OUT_DIR. The links are relative (`<capture>/report.html`), so the folder can be moved whole.
"""

import html
from pathlib import Path
from urllib.parse import quote

from flashbrdf.files.atomic import write_text
from flashbrdf.pipeline.report_text import PAGE_DIR, PAGE_NAME, inline_markdown

INDEX_NAME = "index.html"
LOG_DIR = "logs"  # OUT_DIR/logs/<capture>.log: what `run` printed for each capture
# How the index starts: a later batch knows the file as its own by it (batch._check_batch_folder)
INDEX_HEAD = "<!doctype html>\n<!-- flashbrdf batch index -->\n"


def _number(value, digits=3):
    return "" if value is None else f"{value:.{digits}f}"


def write_batch_index(out_dir, rows, methods=(), header_lines=()):
    """Write OUT_DIR/index.html. rows: batch's summary rows ({"capture", "status", "reason",
    "seconds", "delta_e_log": {method: mean ΔE-log, "method/photo": ...}}); methods: the ΔE-log
    columns, in order; header_lines: summary.md's markdown lines above the table."""
    out_dir = Path(out_dir)
    methods = list(methods) or list(dict.fromkeys(
        k for r in rows for k in (r.get("delta_e_log") or {}) if "/" not in k))
    head = "".join(f"<th>ΔE log {html.escape(m)}</th>" for m in methods)
    body = []
    for r in rows:
        name = str(r["capture"])
        page = out_dir / name / PAGE_NAME
        ok = r.get("status") == "ok"
        link = html.escape(name)
        if page.is_file() and ok:
            link = f'<a href="{quote(name)}/{PAGE_NAME}">{link}</a>'
        elif page.is_file():  # a rerun failed: its folder still holds an earlier run's report
            link += (f' (<a href="{quote(name)}/{PAGE_NAME}">an earlier run\'s report</a>, '
                     "not of these inputs or options)")
        reason = html.escape(str(r.get("reason") or ""))
        if not ok and (out_dir / LOG_DIR / f"{name}.log").is_file():  # the traceback is there
            reason += f' (<a href="{LOG_DIR}/{quote(name)}.log">log</a>)'
        values = [(r.get("delta_e_log") or {}).get(m) for m in methods]
        best = min((v for v in values if v is not None), default=None)
        # an ok capture with no ΔE compared nothing (no reference photo, or no compared
        # pixel): said, not a blank cell that reads as a lost value
        missing = ("<td title='nothing compared: no reference photo, or none that sees the "
                   "object'>–</td>"
                   if ok and best is None else "<td title='not compared'>–</td>" if ok else
                   "<td></td>")
        cells = "".join(missing if v is None else
                        f'<td{" class=best" if v == best else ""}>{_number(v)}</td>'
                        for v in values)
        body.append(f"<tr><td>{link}</td><td class={'ok' if ok else 'failed'}>"
                    f"{html.escape(str(r.get('status', '')))}</td>{cells}"
                    f"<td>{_number(r.get('seconds'), 1)}</td>"
                    f"<td class=reason>{reason}</td></tr>")
    notes = "".join(f"<li>{inline_markdown(line[2:] if line.startswith('- ') else line)}</li>"
                    for line in header_lines if line.strip())
    css = (PAGE_DIR / "report.css").read_text(encoding="utf-8")
    page = (INDEX_HEAD + '<html lang="en"><head><meta charset="utf-8">'
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>flashbrdf batch</title><style>{css}\n"
            "td.ok { color: var(--good); } td.failed { color: var(--bad); font-weight: 600; }"
            " td.reason { text-align: left; color: var(--muted); }</style></head><body>"
            '<header class="top"><h1>flashbrdf batch</h1><nav><a href="summary.md">summary.md'
            '</a> <a href="summary.csv">summary.csv</a></nav></header><main><section>'
            f"<h2>{len(rows)} capture(s)</h2><ul>{notes}</ul>"
            "<p class=hint>Each capture's name opens its report.html (renders, BRDF, "
            "materials). ΔE log: the mean over its reference photos; the best per capture in "
            "bold; –: nothing compared (no reference photo, or none that sees the object).</p>"
            f"<table><thead><tr><th>capture</th><th>status</th>{head}<th>seconds</th>"
            f"<th>reason</th></tr></thead><tbody>{''.join(body)}</tbody></table>"
            "</section></main></body></html>\n")
    write_text(out_dir / INDEX_NAME, page)
