"""The text of the report pages as HTML: report.md's summary table, notes and warnings
(report.html shows them before its scripts run), and the little markdown they use. Light on
imports: `batch`'s client writes its index.html with it."""

import html
import math
import re
from pathlib import Path

PAGE_DIR = Path(__file__).with_name("report_page")
PAGE_NAME = "report.html"


def finite(value):
    """value as a float, None when missing or not finite."""
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def inline_markdown(text):
    """The little markdown report.md's notes use, as HTML: `code`, **bold**, [text](link) and
    ![alt](figure) (a link to the figure: the page loads nothing from outside itself)."""
    out = html.escape(str(text), quote=True)
    out = re.sub(r"`([^`]+)`", r"<code>\1</code>", out)
    out = re.sub(r"\*\*([^*]+)\*\*", r"<strong>\1</strong>", out)
    out = re.sub(r"!\[([^\]]*)\]\(([^)\s]+)\)", r'<a href="\2">\1 (figure)</a>', out)
    out = re.sub(r"\[([^\]]+)\]\(([^)\s]+)\)", r'<a href="\2">\1</a>', out)
    return out


def _paragraphs(text):
    """Markdown paragraphs and '- ' lists as HTML."""
    parts = []
    for block in re.split(r"\n\s*\n", str(text).strip()):
        lines = block.splitlines()
        items = [k for k, line in enumerate(lines) if line.startswith("- ")]
        if items:
            head = " ".join(lines[:items[0]])
            listed = []
            for k in items:
                end = next((j for j in items if j > k), len(lines))
                listed.append(" ".join(line.strip() for line in lines[k:end])[2:])
            parts.append((f"<p>{inline_markdown(head)}</p>" if head else "") + "<ul>"
                         + "".join(f"<li>{inline_markdown(i)}</li>" for i in listed) + "</ul>")
        else:
            parts.append(f"<p>{inline_markdown(' '.join(lines))}</p>")
    return "\n".join(parts)


def _num(value, digits=2):
    value = finite(value)
    return "–" if value is None else f"{value:.{digits}f}"


def summary_html(report, level_note=None, how_to_read=None):
    """The summary section: report.md's table (with the level column), the level note, the
    coverage, warnings, notes and stage timings."""
    parts = ['<h2 id="summary-h">Summary</h2>']
    summary = report.get("summary") or {}
    if summary:
        means = {m: finite(s["delta_e_log_mean"]["mean"]) for m, s in summary.items()}
        best = min((v for v in means.values() if v is not None), default=None)
        rows = []
        for method, s in summary.items():
            level = s.get("level_ratio_rgb")
            level = "–" if level is None else ", ".join(_num(v) for v in level)
            css = ' class="best"' if best is not None and means[method] == best else ""
            matched = s.get("level_matched")
            matched = "–" if matched is None else (
                f"{_num(matched['delta_e_log_mean']['mean'])} / "
                f"{_num(matched['delta_e_log_mean']['median'])}; ×{_num(matched['scale'], 3)}")
            rows.append(
                f"<tr><td>{html.escape(str(method))}</td><td>{s['references']}</td>"
                f"<td{css}>{_num(s['delta_e_log_mean']['mean'])} / "
                f"{_num(s['delta_e_log_mean']['median'])}</td><td>{matched}</td>"
                f"<td>{_num(s['rel_rmse']['mean'], 3)} / {_num(s['rel_rmse']['median'], 3)}</td>"
                f"<td>{level}</td></tr>")
        parts.append("<table><thead><tr><th>method</th><th>references</th><th>ΔE log mean "
                     "(mean / median over references)</th><th>ΔE log level-matched (mean / "
                     "median; scale)</th><th>rel_rmse (mean / median)</th>"
                     "<th>reference / render (R, G, B)</th></tr></thead><tbody>"
                     + "".join(rows) + "</tbody></table>")
    if level_note:
        parts.append(f'<div class="note">{_paragraphs(level_note)}</div>')
    cover = report.get("coverage")
    if cover and cover.get("bins_observed"):
        low, high = cover["theta_h_observed_deg"]
        parts.append(f"<p>The flash photo filled {cover['bins_observed']} of 90 θh bins "
                     f"({cover['samples']} pixels), the bins from θh {low:.2g}° to {high:.1f}° "
                     "(bin edges).</p>")
    warnings = report.get("warnings") or []
    if warnings:
        parts.append("<h3>Coverage warnings</h3><ul class=\"warnings\">"
                     + "".join(f"<li>{inline_markdown(w)}</li>" for w in warnings) + "</ul>")
    notes = report.get("notes") or []
    if notes:
        parts.append("<h3>Notes</h3>" + "".join(_paragraphs(n) for n in notes))
    if how_to_read:
        parts.append("<details><summary>How to read the numbers</summary>"
                     + _paragraphs(how_to_read) + "</details>")
    stages = report.get("stages") or {}
    if stages:
        rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{v:.2f}</td></tr>"
                       for k, v in stages.items())
        parts.append("<details><summary>Stage timings (total "
                     f"{sum(stages.values()):.1f} s)</summary><table><thead><tr><th>stage</th>"
                     f"<th>seconds</th></tr></thead><tbody>{rows}</tbody></table></details>")
    return "\n".join(parts)
