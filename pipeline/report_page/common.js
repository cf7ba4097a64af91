// flashbrdf report.html, part 1: data decoding, colour maths and a small canvas plot helper.
// Plain ES2020, no library. Everything the page needs is embedded in it.
"use strict";

const META = JSON.parse(document.getElementById("report-meta").textContent);

function base64Bytes(text) {
  if (Uint8Array.fromBase64) return Uint8Array.fromBase64(text);
  const bin = atob(text);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

function float32s(text) {
  const bytes = base64Bytes(text);
  return new Float32Array(bytes.buffer, bytes.byteOffset, bytes.byteLength / 4);
}

// float16 -> float32 for every bit pattern, built once (the images are stored as float16).
const HALF_TABLE = (() => {
  const table = new Float32Array(65536);
  for (let h = 0; h < 65536; h++) {
    const sign = h & 0x8000 ? -1 : 1, exp = (h >> 10) & 0x1f, frac = h & 0x3ff;
    table[h] = exp === 0 ? sign * frac * 2 ** -24
      : exp === 31 ? (frac ? NaN : sign * Infinity)
      : sign * (1 + frac / 1024) * 2 ** (exp - 15);
  }
  return table;
})();

// A block's bytes: deflate (zlib) of each array's float16 low-byte plane then high-byte plane.
async function inflateBlock(id) {
  const bytes = base64Bytes(document.getElementById(id).textContent);
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}

function halfArray(bytes, offset, count, scale) {
  const out = new Float32Array(count);
  const lo = offset, hi = offset + count;
  for (let i = 0; i < count; i++) out[i] = HALF_TABLE[bytes[lo + i] | (bytes[hi + i] << 8)] * scale;
  return out;
}

// The display transform: linear value times gain, clipped to [0, 1], sRGB-encoded to 8 bits.
// pipeline/report_data.py:expose_to_srgb8 is the same, for the tests.
function encode8(v) {
  if (!(v > 0)) return 0;
  if (v >= 1) return 255;
  const s = v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055;
  return Math.floor(s * 255 + 0.5);
}

const LUTS = {};
for (const [name, text] of Object.entries(META.luts)) LUTS[name] = base64Bytes(text);

function lutColour(name, t) {  // t in [0, 1] -> [r, g, b] bytes
  const lut = LUTS[name], i = Math.max(0, Math.min(255, Math.floor(t * 255))) * 3;
  return [lut[i], lut[i + 1], lut[i + 2]];
}

function lutGradient(name) {
  const canvas = document.createElement("canvas");
  canvas.width = 256; canvas.height = 1;
  const ctx = canvas.getContext("2d"), img = ctx.createImageData(256, 1);
  for (let i = 0; i < 256; i++) {
    img.data.set([...lutColour(name, i / 255), 255], 4 * i);
  }
  ctx.putImageData(img, 0, 0);
  return canvas;
}

const METHOD_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
                        "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];
const LABEL_COLOURS = METHOD_COLOURS;  // tab10, as the report's labels.png figure

function fmt(x, digits = 3) {
  if (x === null || x === undefined || !Number.isFinite(x)) return "–";
  const a = Math.abs(x);
  return a !== 0 && (a < 1e-3 || a >= 1e5) ? x.toExponential(digits - 1) : x.toFixed(digits);
}

// Linear values span decades (a pixel, ρ in 1/sr): the same significant digits at every level,
// 4 for the BRDF tables (float32 on the page), 3 for image pixels (float16, which carries 3.3).
function fmtSig(x, sig = 4) {
  if (x === null || x === undefined || !Number.isFinite(x)) return "–";
  const a = Math.abs(x);
  return a !== 0 && (a < 1e-3 || a >= 1e5) ? x.toExponential(sig - 1) : x.toPrecision(sig);
}

function fmtRGB(values, sig = 4) {
  return values.map((v) => fmtSig(v, sig).padStart(9)).join(" ");
}
const PIXEL_DIGITS = 3;

function el(tag, attrs = {}, children = []) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "text") node.textContent = v;
    else if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v);
  }
  for (const child of children) node.append(child);
  return node;
}

// Luminance (Rec. 709 / linear sRGB) or one channel of an RGB triplet.
function channelValue(r, g, b, channel) {
  return channel === 3 ? 0.2126 * r + 0.7152 * g + 0.0722 * b : [r, g, b][channel];
}
const CHANNEL_NAMES = ["R", "G", "B", "Y"];

// A plot area on a canvas: data -> pixel mappings, ticks and labels. The canvas is drawn at the
// device pixel ratio so that text stays sharp; sizes below are CSS pixels.
class Axes {
  constructor(canvas, box, x, y) {
    const ratio = window.devicePixelRatio || 1;
    this.canvas = canvas;
    this.cssWidth = canvas.width / (canvas.dataset.ratio || 1);
    this.cssHeight = canvas.height / (canvas.dataset.ratio || 1);
    if (!canvas.dataset.ratio) {
      canvas.dataset.ratio = ratio;
      canvas.width = Math.round(this.cssWidth * ratio);
      canvas.height = Math.round(this.cssHeight * ratio);
    }
    this.ratio = Number(canvas.dataset.ratio);
    this.ctx = canvas.getContext("2d");
    this.ctx.setTransform(this.ratio, 0, 0, this.ratio, 0, 0);
    this.ctx.clearRect(0, 0, this.cssWidth, this.cssHeight);
    this.box = box;  // {left, top, width, height} in CSS pixels
    this.x = x; this.y = y;  // {min, max, log?, sqrt?}
  }
  static scale(axis, v) {
    const f = (t) => (axis.log ? Math.log10(t) : axis.sqrt ? Math.sqrt(t) : t);
    return (f(v) - f(axis.min)) / (f(axis.max) - f(axis.min));
  }
  px(v) { return this.box.left + Axes.scale(this.x, v) * this.box.width; }
  py(v) { return this.box.top + (1 - Axes.scale(this.y, v)) * this.box.height; }
  // canvas event -> position in CSS pixels of the canvas
  eventPoint(event) {
    const rect = this.canvas.getBoundingClientRect();
    return [(event.clientX - rect.left) * this.cssWidth / rect.width,
            (event.clientY - rect.top) * this.cssHeight / rect.height];
  }
  frame(xLabel, yLabel, xTicks, yTicks, yFlip = false) {
    const c = this.ctx, b = this.box;
    c.strokeStyle = "#888"; c.lineWidth = 1;
    c.strokeRect(b.left, b.top, b.width, b.height);
    c.fillStyle = "#333"; c.font = "11px system-ui, sans-serif";
    c.textAlign = "center"; c.textBaseline = "top";
    for (const t of xTicks) {
      const x = this.px(t);
      c.beginPath(); c.moveTo(x, b.top + b.height); c.lineTo(x, b.top + b.height + 4); c.stroke();
      c.fillText(String(t), x, b.top + b.height + 5);
    }
    c.textAlign = "right"; c.textBaseline = "middle";
    for (const t of yTicks) {
      const y = yFlip ? b.top + Axes.scale(this.y, t) * b.height : this.py(t);
      c.beginPath(); c.moveTo(b.left - 4, y); c.lineTo(b.left, y); c.stroke();
      c.fillText(tickLabel(t, this.y.log), b.left - 6, y);
    }
    c.textAlign = "center"; c.textBaseline = "bottom";
    c.fillText(xLabel, b.left + b.width / 2, this.cssHeight - 2);
    c.save(); c.translate(12, b.top + b.height / 2); c.rotate(-Math.PI / 2);
    c.textBaseline = "middle"; c.fillText(yLabel, 0, 0); c.restore();
  }
  grid(yTicks) {
    const c = this.ctx;
    c.strokeStyle = "#0000001a";
    for (const t of yTicks) {
      const y = this.py(t);
      c.beginPath(); c.moveTo(this.box.left, y); c.lineTo(this.box.left + this.box.width, y); c.stroke();
    }
  }
}

// Decades, and 2x and 5x between them when the range spans less than two decades.
function logTicks(min, max) {
  const ticks = [];
  const steps = Math.log10(max / min) < 2 ? [1, 2, 5] : [1];
  for (let e = Math.floor(Math.log10(min)); e <= Math.ceil(Math.log10(max)); e++) {
    for (const s of steps) {
      const t = s * 10 ** e;
      if (t >= min && t <= max) ticks.push(t);
    }
  }
  return ticks;
}

// 0 to max in steps of 1, 2 or 5 times a power of ten: about `count` ticks at any scale.
function linearTicks(max, count = 5) {
  if (!(max > 0)) return [0];
  const raw = max / count, power = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 5, 10].map((s) => s * power).find((s) => s >= raw);
  const ticks = [];
  for (let k = 0; k * step <= max * (1 + 1e-9); k++) ticks.push(Number((k * step).toPrecision(6)));
  return ticks;
}

function tickLabel(t, log) {
  if (!log) return String(Number(t.toPrecision(6)));
  const e = Math.round(Math.log10(t));
  return Math.abs(t / 10 ** e - 1) < 1e-9 ? `1e${e}` : String(Number(t.toPrecision(2)));
}

// A legend drawn on the canvas; returns the boxes so that a click can toggle a series.
function drawLegend(ctx, items, x, y) {
  const boxes = [];
  ctx.font = "11px system-ui, sans-serif"; ctx.textAlign = "left"; ctx.textBaseline = "middle";
  for (const item of items) {
    const width = ctx.measureText(item.label).width + 26;
    ctx.globalAlpha = item.hidden ? 0.35 : 1;
    ctx.strokeStyle = item.colour; ctx.fillStyle = item.colour; ctx.lineWidth = 2;
    ctx.setLineDash(item.dash || []);
    ctx.beginPath(); ctx.moveTo(x, y); ctx.lineTo(x + 18, y); ctx.stroke();
    ctx.setLineDash([]);
    if (item.dot) { ctx.beginPath(); ctx.arc(x + 9, y, 3, 0, 2 * Math.PI); ctx.fill(); }
    ctx.fillStyle = "#222"; ctx.fillText(item.label, x + 22, y);
    ctx.globalAlpha = 1;
    boxes.push({x, y: y - 7, w: width, h: 14, item});
    x += width + 8;
  }
  return boxes;
}

// Arrow keys on a focused plot move a cursor over its cells (Shift: 10), so that every readout
// the mouse gives is reachable from the keyboard; the first key lands on `start`. size: [rows,
// cols], start: [row, col], or functions giving them; onMove(row, col). current(): where the
// cursor is now, when something else (the mouse) moves it too; by default its own last cell.
function keyCursor(canvas, size, onMove, start = [0, 0], current = null) {
  canvas.tabIndex = 0;
  let at = null;
  const value = (v) => (typeof v === "function" ? v() : v);
  canvas.addEventListener("keydown", (e) => {
    const step = {ArrowUp: [-1, 0], ArrowDown: [1, 0], ArrowLeft: [0, -1], ArrowRight: [0, 1]}[e.key];
    if (!step) return;
    e.preventDefault();
    const n = e.shiftKey ? 10 : 1, [rows, cols] = value(size), now = current ? current() : at;
    at = now ? [now[0] + step[0] * n, now[1] + step[1] * n] : value(start).slice();
    at = [Math.max(0, Math.min(rows - 1, at[0])), Math.max(0, Math.min(cols - 1, at[1]))];
    onMove(at[0], at[1]);
  });
}

