// flashbrdf report.html, part 3: the BRDF (heat maps with uncertainty, the observed slice with
// each method's θd = 0 curve, the lobe in the plane of incidence, the Principled fit) and the
// materials. Tables are ρ(θh, θd) (90 x 90 x 3, 1/sr) on MERL's bins.
"use strict";

const HALF_PI = Math.PI / 2;
const Z90 = 1.6448536269514722;   // half-width of a unit normal's central 90% interval
const THETA_H_DEG = Array.from({length: 90}, (_, i) => 90 * ((i + 0.5) / 90) ** 2);
const B = {dataset: 0, channel: 3, hidden: new Set(), decoded: new Map()};

function dataset(index) {  // META.brdf[index] with its base64 arrays decoded, once
  if (B.decoded.has(index)) return B.decoded.get(index);
  const d = META.brdf[index];
  const out = {name: d.name, methods: {}, observed: null};
  if (d.observed) {
    out.observed = {rho: float32s(d.observed.rho), n: d.observed.n,
                    spread: d.observed.spread ? float32s(d.observed.spread) : null};
  }
  for (const [m, e] of Object.entries(d.methods)) {
    out.methods[m] = {table: float32s(e.table), inPlane: e.in_plane ? float32s(e.in_plane) : null,
                      variance: e.variance ? float32s(e.variance) : null,
                      constant: e.variance_constant ?? null, label: e.variance_label,
                      note: e.variance_note ?? null, offset: e.interval_offset ?? null};
  }
  B.decoded.set(index, out);
  return out;
}

function methodColour(m) {
  const k = META.brdf_methods.indexOf(m);
  return METHOD_COLOURS[(k < 0 ? 0 : k) % 10];
}

function tableValue(table, i, j, channel) {
  const o = 3 * (90 * i + j);
  return channelValue(table[o], table[o + 1], table[o + 2], channel);
}

// ρ at (θh, θd) in radians: bilinear between bin centres on MERL's coordinates (square root in
// θh), over the finite neighbours only.
function lookup(table, thetaH, thetaD, channel) {
  const u = Math.min(89, Math.max(0, Math.sqrt(Math.max(thetaH, 0) / HALF_PI) * 90 - 0.5));
  const v = Math.min(89, Math.max(0, thetaD / HALF_PI * 90 - 0.5));
  const i0 = Math.floor(u), j0 = Math.floor(v), i1 = Math.min(i0 + 1, 89), j1 = Math.min(j0 + 1, 89);
  const fu = u - i0, fv = v - j0;
  let total = 0, weight = 0;
  for (const [i, j, w] of [[i0, j0, (1 - fu) * (1 - fv)], [i1, j0, fu * (1 - fv)],
                           [i0, j1, (1 - fu) * fv], [i1, j1, fu * fv]]) {
    const value = tableValue(table, i, j, channel);
    if (Number.isFinite(value) && w > 0) { total += w * value; weight += w; }
  }
  return weight > 0 ? total / weight : NaN;
}

// θh, θd of the in-plane directions: light at θi on the left, view at θo (positive: the right).
function halfDiff(thetaI, thetaO) {
  const wi = [-Math.sin(thetaI), Math.cos(thetaI)], wo = [Math.sin(thetaO), Math.cos(thetaO)];
  const h = [wi[0] + wo[0], wi[1] + wo[1]], norm = Math.hypot(h[0], h[1]);
  const hx = h[0] / norm, hz = h[1] / norm;
  return [Math.acos(Math.min(1, hz)), Math.acos(Math.min(1, wi[0] * hx + wi[1] * hz))];
}

function observedValue(obs, i, channel) {
  const o = 3 * i;
  return obs.n[i] > 0 ? channelValue(obs.rho[o], obs.rho[o + 1], obs.rho[o + 2], channel) : NaN;
}

// ---- the observed slice with every method's θd = 0 curve ----------------------------------

function slicePlot(canvas, d, channel, readout, legend = true) {
  const methods = Object.keys(d.methods).filter((m) => !B.hidden.has(m));
  const values = [];
  for (let i = 0; i < 90; i++) {
    if (d.observed) values.push(observedValue(d.observed, i, channel));
    for (const m of methods) values.push(tableValue(d.methods[m].table, i, 0, channel));
  }
  const positive = values.filter((v) => v > 0);
  const top = positive.length ? Math.max(...positive) * 2 : 1;
  const bottom = positive.length ? Math.max(Math.min(...positive) / 2, top * 1e-7) : 1e-3;
  const cssW = canvas.width / (canvas.dataset.ratio || 1), cssH = canvas.height / (canvas.dataset.ratio || 1);
  const sqrt = document.getElementById("slice-sqrt").checked;
  const ax = new Axes(canvas, {left: 62, top: 30, width: cssW - 80, height: cssH - 68},
                      {min: 0, max: 90, sqrt}, {min: bottom, max: top, log: true});
  const yTicks = logTicks(bottom, top);
  ax.grid(yTicks);
  ax.frame(sqrt ? "θh (degrees, square-root axis)" : "θh (degrees)", `ρ ${CHANNEL_NAMES[channel]} (1/sr)`,
           sqrt ? [0, 1, 2, 5, 10, 20, 30, 45, 60, 90] : [0, 10, 20, 30, 40, 50, 60, 70, 80, 90], yTicks);
  const c = ax.ctx;
  c.save(); c.beginPath(); c.rect(ax.box.left, ax.box.top, ax.box.width, ax.box.height); c.clip();
  for (const m of methods) {
    c.strokeStyle = methodColour(m); c.lineWidth = 1.6; c.beginPath();
    let pen = false;
    for (let i = 0; i < 90; i++) {
      const v = tableValue(d.methods[m].table, i, 0, channel);
      if (v > 0) { c[pen ? "lineTo" : "moveTo"](ax.px(THETA_H_DEG[i]), ax.py(v)); pen = true; } else pen = false;
    }
    c.stroke();
  }
  if (d.observed) {
    c.fillStyle = c.strokeStyle = "#000"; c.lineWidth = 1;
    for (let i = 0; i < 90; i++) {
      const v = observedValue(d.observed, i, channel);
      if (!(v > 0)) continue;
      const x = ax.px(THETA_H_DEG[i]), y = ax.py(v);
      if (d.observed.spread) {
        const s = d.observed.spread, o = 3 * i;
        const err = Math.min(channelValue(s[o], s[o + 1], s[o + 2], channel) || 0, v * 0.999);
        c.beginPath(); c.moveTo(x, ax.py(v + err)); c.lineTo(x, ax.py(v - err)); c.stroke();
      }
      c.beginPath(); c.arc(x, y, 2.6, 0, 2 * Math.PI); c.fill();
    }
  }
  c.restore();
  if (legend) {
    const items = [];
    if (d.observed) items.push({label: "observed (flash photo)", colour: "#000", dot: true, key: null});
    for (const m of Object.keys(d.methods)) {
      items.push({label: `${m}: θd = 0`, colour: methodColour(m), hidden: B.hidden.has(m), key: m});
    }
    canvas.legend = drawLegend(c, items, ax.box.left, 14);
  }
  canvas.axes = ax;
  if (legend && !canvas.legendHooked) {  // the material plots' legends too
    canvas.legendHooked = true;
    canvas.addEventListener("click", (e) => {
      const [x, y] = canvas.axes.eventPoint(e);
      for (const b of canvas.legend || []) {
        if (b.item.key && x >= b.x && x <= b.x + b.w && y >= b.y && y <= b.y + b.h) toggleMethod(b.item.key);
      }
    });
  }
  if (readout && !canvas.hooked) {
    canvas.hooked = true;
    canvas.addEventListener("mousemove", (e) => {
      const [x] = canvas.axes.eventPoint(e);
      const t = Math.max(0, (x - canvas.axes.box.left) / canvas.axes.box.width);
      const deg = canvas.axes.x.sqrt ? 90 * t * t : 90 * t;
      let i = 0;
      for (let k = 1; k < 90; k++) if (Math.abs(THETA_H_DEG[k] - deg) < Math.abs(THETA_H_DEG[i] - deg)) i = k;
      sliceReadout(readout, i);
    });
    keyCursor(canvas, [1, 90], (_, i) => sliceReadout(readout, i));  // ← →: the θh bin
  }
}

function sliceReadout(readout, i) {
  const ds = dataset(B.dataset), ch = B.channel;
  const parts = [`θh bin ${i} (${THETA_H_DEG[i].toFixed(2)}°)`];
  if (ds.observed) parts.push(`observed ${fmtSig(observedValue(ds.observed, i, ch))} (${ds.observed.n[i]} px)`);
  for (const m of Object.keys(ds.methods)) parts.push(`${m} ${fmtSig(tableValue(ds.methods[m].table, i, 0, ch))}`);
  readout.textContent = readoutPrefix() + parts.join(" · ") + " 1/sr";
}

// One method shown or hidden on every slice plot, from a legend click or its box (the boxes are
// what the keyboard reaches).
function toggleMethod(m) {
  if (B.hidden.has(m)) B.hidden.delete(m); else B.hidden.add(m);
  for (const box of document.querySelectorAll("#method-toggles input")) {
    box.checked = !B.hidden.has(box.value);
  }
  drawBrdf();
  if (META.materials) META.materials.draw();
}

function methodToggles() {
  const box = document.getElementById("method-toggles");
  for (const m of META.brdf_methods) {
    const input = el("input", {type: "checkbox", value: m});
    input.checked = !B.hidden.has(m);
    input.addEventListener("change", () => toggleMethod(m));
    box.append(el("label", {class: "control"}, [input, el("span", {class: "swatch",
      style: `background:${methodColour(m)}`}), m]));
  }
}

// ---- the lobe in the plane of incidence ----------------------------------------------------

// In the plane of incidence φd = 0: a 3D table is read there (inPlane), not at its φd mean.
function polarValues(d, thetaI, channel, withCos) {
  const angles = [];
  for (let a = -89.5; a <= 89.5; a += 0.5) angles.push(a);
  const curves = {};
  for (const m of Object.keys(d.methods)) {
    const table = d.methods[m].inPlane || d.methods[m].table;
    curves[m] = angles.map((a) => {
      const t = a * Math.PI / 180, [th, td] = halfDiff(thetaI, t);
      return lookup(table, th, td, channel) * (withCos ? Math.cos(t) : 1);
    });
  }
  return {angles, curves};
}

function polarPlot() {
  document.getElementById("polar-readout").textContent = "";  // it read the lobe drawn before
  const canvas = document.getElementById("polar-plot"), d = dataset(B.dataset);
  const thetaIDeg = Number(document.getElementById("theta-i").value);
  const thetaI = thetaIDeg * Math.PI / 180, channel = B.channel;
  const withCos = document.getElementById("lobe-quantity").value === "cos";
  const logRadius = document.getElementById("lobe-log").checked;
  const {angles, curves} = polarValues(d, thetaI, channel, withCos);
  // the observed retro-reflection: θo = −θi, so θh = θi and θd = 0 (what the flash measured)
  let retro = NaN;
  if (d.observed) {
    const u = Math.sqrt(thetaI / HALF_PI) * 90 - 0.5, i = Math.max(0, Math.min(89, Math.round(u)));
    retro = observedValue(d.observed, i, channel) * (withCos ? Math.cos(thetaI) : 1);
  }
  const shown = Object.keys(curves).filter((m) => !B.hidden.has(m));
  const all = shown.flatMap((m) => curves[m]).concat([retro]).filter((v) => v > 0);
  const vmax = all.length ? Math.max(...all) : 1;
  const radius = (v) => (!(v > 0) ? 0 : logRadius ? Math.max(0, 1 + Math.log10(v / vmax) / 4) : v / vmax);
  const ax = new Axes(canvas, {left: 0, top: 0, width: 1, height: 1}, {min: 0, max: 1}, {min: 0, max: 1});
  const c = ax.ctx, W = ax.cssWidth, H = ax.cssHeight;
  const R0 = Math.min(H - 56, W / 2 - 120), cx = R0 + 40, cy = H - 26;
  c.strokeStyle = "#0000002a"; c.lineWidth = 1; c.fillStyle = "#555"; c.font = "11px system-ui, sans-serif";
  for (const f of [0.25, 0.5, 0.75, 1]) { c.beginPath(); c.arc(cx, cy, R0 * f, Math.PI, 2 * Math.PI); c.stroke(); }
  c.textAlign = "center"; c.textBaseline = "bottom";
  for (const a of [-90, -60, -30, 0, 30, 60, 90]) {
    const t = a * Math.PI / 180;
    c.beginPath(); c.moveTo(cx, cy); c.lineTo(cx + R0 * Math.sin(t), cy - R0 * Math.cos(t)); c.stroke();
    c.fillText(`${a}°`, cx + (R0 + 12) * Math.sin(t), cy - (R0 + 4) * Math.cos(t));
  }
  c.strokeStyle = "#444"; c.beginPath(); c.moveTo(cx - R0 - 10, cy); c.lineTo(cx + R0 + 10, cy); c.stroke();
  // incidence (solid, with the light) and the mirror direction (dashed)
  c.strokeStyle = "#d4a000"; c.fillStyle = "#d4a000"; c.lineWidth = 2;
  const lx = cx - R0 * Math.sin(thetaI), ly = cy - R0 * Math.cos(thetaI);
  c.beginPath(); c.moveTo(lx, ly); c.lineTo(cx, cy); c.stroke();
  c.beginPath(); c.arc(lx, ly, 6, 0, 2 * Math.PI); c.fill();
  c.setLineDash([5, 4]); c.lineWidth = 1;
  c.beginPath(); c.moveTo(cx, cy); c.lineTo(cx + R0 * Math.sin(thetaI), cy - R0 * Math.cos(thetaI)); c.stroke();
  c.setLineDash([]);
  for (const m of shown) {
    c.strokeStyle = methodColour(m); c.lineWidth = 1.8; c.beginPath();
    let pen = false;
    angles.forEach((a, k) => {
      const r = radius(curves[m][k]) * R0, t = a * Math.PI / 180;
      if (Number.isFinite(r)) { c[pen ? "lineTo" : "moveTo"](cx + r * Math.sin(t), cy - r * Math.cos(t)); pen = true; }
      else pen = false;
    });
    c.stroke();
  }
  if (retro > 0) {
    const r = radius(retro) * R0;
    c.fillStyle = "#000"; c.beginPath();
    c.arc(cx - r * Math.sin(thetaI), cy - r * Math.cos(thetaI), 4, 0, 2 * Math.PI); c.fill();
  }
  const items = [{label: `light at θi = ${thetaIDeg}°`, colour: "#d4a000"},
                 {label: "mirror direction", colour: "#d4a000", dash: [5, 4]}];
  if (retro > 0) items.push({label: "observed (θd = 0)", colour: "#000", dot: true});
  for (const m of Object.keys(curves)) items.push({label: m, colour: methodColour(m), hidden: B.hidden.has(m)});
  const lx0 = cx + R0 + 50;
  items.forEach((item, k) => drawLegend(c, [item], lx0, 20 + 18 * k));
  c.fillStyle = "#333"; c.textAlign = "left"; c.textBaseline = "top";
  c.fillText(`radius: ${withCos ? "ρ·cos θo" : "ρ"} ${CHANNEL_NAMES[channel]}, ${logRadius ?
    "log, 4 decades" : "linear"}`, lx0, 24 + 18 * items.length);
  c.fillText(`outer circle: ${fmt(vmax, 3)} 1/sr`, lx0, 40 + 18 * items.length);
  canvas.polar = {cx, cy, angles, curves, retro};
}

function polarHover(e) {
  const canvas = document.getElementById("polar-plot"), p = canvas.polar;
  if (!p) return;
  const rect = canvas.getBoundingClientRect();
  const x = (e.clientX - rect.left) * (canvas.width / canvas.dataset.ratio) / rect.width;
  const y = (e.clientY - rect.top) * (canvas.height / canvas.dataset.ratio) / rect.height;
  const a = Math.atan2(x - p.cx, p.cy - y) * 180 / Math.PI;
  if (Math.abs(a) > 90) return;
  polarReadout(Math.max(0, Math.min(p.angles.length - 1, Math.round((a + 89.5) / 0.5))));
}

function polarReadout(k) {  // k: the index of θo in the plot's angles
  const p = document.getElementById("polar-plot").polar;
  if (!p) return;
  const thetaI = Number(document.getElementById("theta-i").value);
  const [th, td] = halfDiff(thetaI * Math.PI / 180, p.angles[k] * Math.PI / 180);
  document.getElementById("polar-readout").textContent = readoutPrefix() +
    `θo ${p.angles[k].toFixed(1)}° (θh ${(th * 180 / Math.PI).toFixed(1)}°, θd ${(td * 180 / Math.PI).toFixed(1)}°): ` +
    Object.entries(p.curves).map(([m, v]) => `${m} ${fmtSig(v[k])}`).join(" · ");
}

// ---- heat maps ---------------------------------------------------------------------------

function percentile(values, q) {
  const sorted = Float64Array.from(values).sort();
  return sorted.length ? sorted[Math.min(sorted.length - 1, Math.floor(q * (sorted.length - 1)))] : NaN;
}

function heatImage(values, lo, hi, lut) {  // 90 x 90 values -> an offscreen canvas
  const canvas = document.createElement("canvas");
  canvas.width = canvas.height = 90;
  const ctx = canvas.getContext("2d"), img = ctx.createImageData(90, 90);
  for (let k = 0; k < 8100; k++) {
    const v = values[k];
    const rgb = Number.isFinite(v) ? lutColour(lut, (v - lo) / (hi - lo || 1)) : [235, 235, 235];
    img.data.set([...rgb, 255], 4 * k);
  }
  ctx.putImageData(img, 0, 0);
  return canvas;
}

function heatCanvas(values, lo, hi, lut, title, barLabel, onHover) {
  const canvas = el("canvas", {width: "344", height: "290", role: "img", "aria-label": title});
  const ax = new Axes(canvas, {left: 44, top: 22, width: 220, height: 220}, {min: 0, max: 90},
                      {min: 0, max: 90, sqrt: true});
  const c = ax.ctx;
  c.imageSmoothingEnabled = false;
  c.drawImage(heatImage(values, lo, hi, lut), ax.box.left, ax.box.top, ax.box.width, ax.box.height);
  ax.frame("θd (degrees)", "θh (degrees)", [0, 30, 60, 90], [0, 2, 5, 10, 20, 40, 60, 90], true);
  c.font = "12px system-ui, sans-serif"; c.textAlign = "left"; c.textBaseline = "top"; c.fillStyle = "#222";
  c.fillText(title, 44, 3);
  // the colour bar, high at the top, its two ends labelled
  c.save(); c.translate(272, 242); c.rotate(-Math.PI / 2);
  c.drawImage(lutGradient(lut), 0, 0, 256, 1, 0, 0, 220, 10); c.restore();
  c.strokeStyle = "#888"; c.strokeRect(272, 22, 10, 220);
  c.font = "10px system-ui, sans-serif"; c.fillStyle = "#333"; c.textBaseline = "middle";
  c.fillText(fmt(hi, 2), 286, 27); c.fillText(fmt(lo, 2), 286, 237);
  // the bar's label, whole (its unit matters), right of the tick labels: on two lines when one
  // would be longer than the bar
  c.save(); c.translate(314, 132); c.rotate(Math.PI / 2); c.textAlign = "center";
  c.textBaseline = "bottom";
  let lines = [barLabel];
  if (c.measureText(barLabel).width > 220 && barLabel.includes(" ")) {
    const cut = barLabel.lastIndexOf(" ", Math.ceil(barLabel.length / 2)) + 1 || barLabel.indexOf(" ") + 1;
    lines = [barLabel.slice(0, cut).trim(), barLabel.slice(cut)];
  }
  // turned a quarter clockwise, text reads top to bottom and its lines run right to left
  lines.forEach((line, k) => c.fillText(line, 0, -12 * (lines.length - 1 - k))); c.restore();
  canvas.addEventListener("pointermove", (e) => {
    const [x, y] = ax.eventPoint(e);
    const j = Math.floor((x - ax.box.left) / ax.box.width * 90), i = Math.floor((y - ax.box.top) / ax.box.height * 90);
    if (i >= 0 && i < 90 && j >= 0 && j < 90) onHover(i, j);
  });
  keyCursor(canvas, [90, 90], onHover);  // ↑ ↓: θh, ← →: θd
  return canvas;
}

function heatmaps() {
  const box = document.getElementById("heatmaps"), d = dataset(B.dataset), channel = B.channel;
  box.replaceChildren();
  const logs = {}, all = [];
  for (const [m, e] of Object.entries(d.methods)) {
    logs[m] = new Float32Array(8100);
    for (let k = 0; k < 8100; k++) {
      const v = channelValue(e.table[3 * k], e.table[3 * k + 1], e.table[3 * k + 2], channel);
      logs[m][k] = v > 0 ? Math.log10(v) : NaN;
      if (v > 0) all.push(logs[m][k]);
    }
  }
  const lo = percentile(all, 0.01), hi = percentile(all, 0.995);
  const readout = document.getElementById("heat-readout");
  for (const [m, e] of Object.entries(d.methods)) {
    const show = (i, j) => {
      const o = 3 * (90 * i + j), t = e.table;
      let text = readoutPrefix() + `${m}: θh ${THETA_H_DEG[i].toFixed(2)}°, θd ${(j + 0.5).toFixed(1)}° → ρ ` +
        `(${fmtRGB([t[o], t[o + 1], t[o + 2]]).trim()}) 1/sr`;
      if (e.variance) text += ` · ${e.label} (${fmtRGB([e.variance[o], e.variance[o + 1], e.variance[o + 2]]).trim()})`;
      if (e.variance && e.offset !== null) {
        // per channel of ln(1 + ρ/ε): the central 90% interval is (ρ + ε)·exp(±1.645 σ) − ε
        const bound = (sign) => [0, 1, 2].map((c) => Math.max(
          (t[o + c] + e.offset) * Math.exp(sign * Z90 * Math.sqrt(Math.max(e.variance[o + c], 0))) - e.offset, 0));
        text += ` · 90% interval (${fmtRGB(bound(-1)).trim()}) to (${fmtRGB(bound(1)).trim()}) 1/sr`;
        // the intervals' scale κ was measured on θd > 0 bins; the first column is the flash slice's
        if (j === 0) text += " (θd bin 0, the flash slice's: its coverage was not measured)";
      }
      readout.textContent = text;
    };
    const row = el("div", {class: "heatcard"});
    row.append(heatCanvas(logs[m], lo, hi, "magma", `${m}: log10 ρ ${CHANNEL_NAMES[channel]}` +
                          (e.inPlane ? ", φd mean" : ""), "log10 ρ (1/sr)", show));
    if (e.variance) {
      const values = new Float32Array(8100);
      for (let k = 0; k < 8100; k++) {
        const o = 3 * k;
        values[k] = channel === 3 ? (e.variance[o] + e.variance[o + 1] + e.variance[o + 2]) / 3 : e.variance[o + channel];
      }
      const finite = Array.from(values).filter(Number.isFinite);
      const name = /CIELAB/.test(e.label) ? (channel === 3 ? "mean of L*a*b*" : ["L*", "a*", "b*"][channel])
        : channel === 3 ? "mean of RGB" : CHANNEL_NAMES[channel];
      row.append(heatCanvas(values, 0, percentile(finite, 0.99), "viridis", `${m}: variance ${name}`, e.label, show));
    } else {
      row.append(el("p", {class: "novar", text: e.constant !== null ?
        `${e.label}: ${fmt(e.constant, 3)} in every bin and channel (std ${fmt(Math.sqrt(Math.max(e.constant, 0)), 3)}).` :
        e.note || `${m} gives no per-bin uncertainty.`}));
    }
    box.append(row);
  }
}

function principled() {
  const box = document.getElementById("principled");
  if (!META.principled.length) return;
  box.append(el("h3", {text: "The Principled fit (run --export)"}));
  for (const fit of META.principled) {
    const rows = Object.entries(fit.params).map(([k, v]) => el("tr", {}, [el("td", {text: k}),
      el("td", {text: Array.isArray(v) ? v.map((x) => fmt(x, 3)).join(", ") : fmt(v, 3)})]));
    const errors = [`2D LAB-log error against the table: ${fmt(fit.fit.lab_log_2d, 2)}`];
    if (Number.isFinite(fit.fit.render_delta_e_log)) errors.push(`sphere render ΔE log: ${fmt(fit.fit.render_delta_e_log, 2)}`);
    box.append(el("p", {text: `${fit.name} (Mitsuba 3 principled parameters). ${errors.join("; ")}.`}),
               el("table", {}, [el("tbody", {}, rows)]));
  }
}

// The readouts name the material when there are several, and are cleared on every redraw: a
// value read off the material or channel drawn before must not stand beside the new plots.
function readoutPrefix() {
  return META.brdf.length > 1 ? `${dataset(B.dataset).name} · ` : "";
}

function drawBrdf() {
  for (const id of ["slice-readout", "heat-readout"]) document.getElementById(id).textContent = "";
  slicePlot(document.getElementById("slice-plot"), dataset(B.dataset), B.channel,
            document.getElementById("slice-readout"));
  polarPlot();
  heatmaps();
}

// ---- materials ---------------------------------------------------------------------------

function materials() {
  const info = META.materials;
  if (!info) return;
  document.getElementById("materials").hidden = false;
  document.getElementById("nav-materials").hidden = false;
  const canvas = document.getElementById("labels-canvas"), lab = info.labels;
  canvas.width = lab.width; canvas.height = lab.height;
  const ctx = canvas.getContext("2d"), img = ctx.createImageData(lab.width, lab.height);
  const labels = base64Bytes(lab.data);
  const rgb = LABEL_COLOURS.map((h) => [1, 3, 5].map((k) => parseInt(h.slice(k, k + 2), 16)));
  labels.forEach((k, p) => img.data.set(k ? [...rgb[(k - 1) % 10], 255] : [0, 0, 0, 255], 4 * p));
  ctx.putImageData(img, 0, 0);
  const rows = info.entries.map((e) => el("tr", {}, [
    el("td", {}, [el("span", {class: "swatch", style: `background:${LABEL_COLOURS[(e.label - 1) % 10]}`}),
                  `material ${e.label}`]),
    el("td", {text: String(e.pixels)}), el("td", {text: `${(100 * e.share).toFixed(1)}%`}),
    el("td", {text: e.bins_filled === null ? "–" : `${e.bins_filled} / 90`})]));
  document.getElementById("materials-table").append(
    el("p", {class: "hint", text: info.reason}),
    el("table", {}, [el("thead", {}, [el("tr", {}, ["material", "pixels", "share", "θh bins observed"]
      .map((t) => el("th", {text: t})))]), el("tbody", {}, rows)]));
  const box = document.getElementById("material-slices");
  info.entries.forEach((e) => {
    const index = META.brdf.findIndex((d) => d.material === e.label);
    if (index < 0) return;
    const plot = el("canvas", {class: "plot", width: "560", height: "260",
      "aria-label": `material ${e.label}: observed slice and predictions`});
    box.append(el("figure", {class: "material"}, [el("figcaption", {}, [el("strong", {text: `material ${e.label}`}),
      el("span", {text: `${(100 * e.share).toFixed(1)}% of the object's pixels`})]), plot]));
    e.plot = plot; e.index = index;
  });
  info.draw = () => info.entries.forEach((e) => e.plot && slicePlot(e.plot, dataset(e.index), B.channel, null, true));
  info.draw();
}

function initBrdf() {
  if (!META.brdf.length) {
    document.getElementById("brdf-ui").hidden = true;
    document.getElementById("brdf-empty").hidden = false;
    return;
  }
  const select = document.getElementById("dataset");
  META.brdf.forEach((d, k) => select.append(el("option", {value: String(k), text: d.name})));
  document.getElementById("dataset-box").hidden = META.brdf.length < 2;
  select.addEventListener("change", () => { B.dataset = Number(select.value); drawBrdf(); });
  const channel = document.getElementById("channel");
  channel.addEventListener("change", () => {
    B.channel = Number(channel.value); drawBrdf();
    if (META.materials) META.materials.draw();
  });
  const thetaI = document.getElementById("theta-i");
  thetaI.addEventListener("input", () => {
    document.getElementById("theta-i-out").textContent = `${thetaI.value}°`; polarPlot();
  });
  document.getElementById("lobe-quantity").addEventListener("change", polarPlot);
  document.getElementById("slice-sqrt").addEventListener("change", () => {
    drawBrdf();
    if (META.materials) META.materials.draw();
  });
  document.getElementById("lobe-log").addEventListener("change", polarPlot);
  document.getElementById("polar-plot").addEventListener("mousemove", polarHover);
  keyCursor(document.getElementById("polar-plot"), [1, 359], (_, k) => polarReadout(k), [0, 179]);
  methodToggles();
  drawBrdf();
  principled();
}
