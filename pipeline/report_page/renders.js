// flashbrdf report.html, part 2: the renders. One frame per method holds that method's render and
// the reference photo (flip, split), with one exposure control for all frames, computed from the
// linear data. Each photo's arrays are inflated when the photo is first shown.
"use strict";

const R = {
  index: 0, stops: META.exposure.initial, flipped: false, split: 0, overlay: false,
  cache: new Map(), frames: [], photo: null,
  point: null,      // {x, y}: the pixel the readouts show (mouse or arrow keys), in shown pixels
  keyCursor: false, // the point was set by the arrow keys: it is marked on the frames
  solo: null,       // the one method shown alone, large (number keys, or its name), or null
};
const NO_DATA_RGB = [255, 0, 255];  // a pixel with a NaN or inf channel (readout: –)
const CACHE_PHOTOS = 6;  // decoded photos kept (a DiLiGenT photo is ~1 MB of float32)

function loadPhoto(index) {
  if (R.cache.has(index)) return R.cache.get(index);
  const p = META.photos[index];
  const promise = inflateBlock(p.block).then((bytes) => {
    const n = p.width * p.height, arrays = {};
    let offset = 0;
    for (const [key, channels] of p.arrays) {
      arrays[key] = halfArray(bytes, offset, n * channels, channels === 3 ? p.scale : 1);
      offset += 2 * n * channels;
    }
    const photo = {meta: p, w: p.width, h: p.height, ref: arrays.reference || null,
                   renders: {}, des: {}};
    for (const m of META.methods) {
      photo.renders[m] = arrays["render:" + m] || null;
      photo.des[m] = arrays["de:" + m] || null;
    }
    return photo;
  });
  R.cache.set(index, promise);
  if (R.cache.size > CACHE_PHOTOS) R.cache.delete(R.cache.keys().next().value);
  return promise;
}

function buildFrames() {
  const box = document.getElementById("frames");
  for (const method of META.methods) {
    const canvas = el("canvas", {tabindex: "0", role: "img",
      "aria-label": `${method}: render and reference photo; click or Enter to flip`});
    const name = el("button", {type: "button", class: "method",
      title: `show ${method} alone, large (key ${META.methods.indexOf(method) + 1}); again: every method`,
      onclick: () => setSolo(R.solo === method ? null : method)}, [el("strong", {text: method})]);
    const caption = el("figcaption", {}, [name, el("span", {class: "de"}), el("span", {class: "which"})]);
    const readout = el("div", {class: "readout", "aria-live": "off"});
    const figure = el("figure", {class: "frame", "data-method": method}, [caption, canvas, readout]);
    box.append(figure);
    const frame = {method, canvas, ctx: canvas.getContext("2d"), caption, readout};
    canvas.addEventListener("click", () => setFlip(!R.flipped));
    canvas.addEventListener("keydown", (e) => {
      if (e.key === "Enter" || e.key === " ") { e.preventDefault(); setFlip(!R.flipped); }
    });
    // one cursor for every frame and the mouse; the first key reads the centre
    keyCursor(canvas, () => (R.photo ? [R.photo.h, R.photo.w] : [0, 0]), (y, x) => keyRead(x, y),
              () => (R.photo ? [R.photo.h >> 1, R.photo.w >> 1] : [0, 0]),
              () => (R.point ? [R.point.y, R.point.x] : null));
    canvas.addEventListener("pointermove", (e) => hover(frame, e));
    canvas.addEventListener("mouseleave", () => { if (!R.keyCursor) clearReadouts(); });
    R.frames.push(frame);
  }
}

// The two images of a frame: A fills it, B is shown left of the split line.
function frameImages(frame) {
  const photo = R.photo, render = photo.renders[frame.method], ref = photo.ref;
  const a = R.flipped ? ref : render, b = R.flipped ? render : ref;
  return [a || b, b || a];
}

function drawFrame(frame) {
  const photo = R.photo;
  if (!photo) return;
  const {w, h} = photo, canvas = frame.canvas;
  if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
  const image = frame.ctx.createImageData(w, h), out = image.data;
  const [a, b] = frameImages(frame);
  const gain = 2 ** R.stops, splitAt = Math.round(R.split / 100 * w);
  const de = R.overlay ? photo.des[frame.method] : null;
  const vmax = META.delta_e_vmax, lut = LUTS.inferno, alpha = META.overlay_alpha;
  for (let y = 0; y < h; y++) {
    for (let x = 0; x < w; x++) {
      const i = y * w + x, src = x < splitAt ? b : a, o = 4 * i;
      if (src && !(Number.isFinite(src[3 * i]) && Number.isFinite(src[3 * i + 1]) &&
                   Number.isFinite(src[3 * i + 2]))) out.set(NO_DATA_RGB, o);
      else for (let c = 0; c < 3; c++) out[o + c] = src ? encode8(src[3 * i + c] * gain) : 0;
      if (de && Number.isFinite(de[i])) {
        // as report_data.overlay_delta_e
        const k = 3 * Math.max(0, Math.min(255, Math.floor(de[i] / vmax * 255)));
        for (let c = 0; c < 3; c++) out[o + c] = Math.floor((1 - alpha) * out[o + c] + alpha * lut[k + c] + 0.5);
      }
      out[o + 3] = 255;
    }
  }
  frame.ctx.putImageData(image, 0, 0);
  if (splitAt > 0 && splitAt < w) {
    frame.ctx.fillStyle = "rgba(255,255,255,0.85)";
    frame.ctx.fillRect(splitAt, 0, 1, h);
  }
  if (R.keyCursor && R.point) {  // the pixel the arrow keys read, ringed so it can be seen
    frame.ctx.strokeStyle = "#00e5ff"; frame.ctx.lineWidth = 1;
    frame.ctx.strokeRect(R.point.x - 1.5, R.point.y - 1.5, 4, 4);
  }
  const shown = R.flipped ? "photo" : "render", other = R.flipped ? "render" : "photo";
  frame.caption.querySelector(".which").textContent = !photo.ref ? "render (no photo)" :
    !photo.renders[frame.method] ? "photo (no render)" :
    splitAt > 0 ? `${splitAt >= w ? other : other + " | " + shown}` : shown;
  const mean = photo.meta.delta_e[frame.method];
  const label = frame.caption.querySelector(".de");
  label.textContent = `ΔE ${fmt(mean, 2)}`;
  label.title = "ΔE log mean of this render against this photo";
}

function drawAll() { R.frames.forEach((f) => { if (!R.solo || f.method === R.solo) drawFrame(f); }); }

// One method alone, at the largest whole zoom (image pixels as squares of whole CSS pixels, as
// in tev) that fits the width and the window's height below the toolbar; below 1×, what fits.
function setSolo(method) {
  R.solo = method;
  document.getElementById("frames").classList.toggle("solo", Boolean(method));
  for (const f of R.frames) f.canvas.closest("figure").hidden = Boolean(method) && f.method !== method;
  sizeFrames();
  drawAll();
}

function sizeFrames() {
  const box = document.getElementById("frames");
  for (const f of R.frames) f.canvas.style.width = "";
  if (!R.solo || !R.photo) return;
  const frame = R.frames.find((f) => f.method === R.solo);
  // the window below the header and the toolbar, stuck at the top once scrolled to the frame,
  // less the caption and the readout
  const above = document.querySelector("header.top").offsetHeight +
    document.querySelector("#renders .toolbar").offsetHeight;
  const high = Math.max(120, window.innerHeight - above - 90);
  const fit = Math.min(box.clientWidth / R.photo.w, high / R.photo.h);
  frame.canvas.style.width = `${R.photo.w * (fit >= 1 ? Math.floor(fit) : fit)}px`;
}

// pointermove, not mousemove: its clientX keeps the fraction of a CSS pixel (mousemove's is
// truncated, which names the pixel left of the pointer's when an image pixel is a CSS pixel
// and a bit wide)
function hover(frame, event) {
  const photo = R.photo;
  if (!photo) return;
  const rect = frame.canvas.getBoundingClientRect();
  const x = Math.floor((event.clientX - rect.left) * photo.w / rect.width);
  const y = Math.floor((event.clientY - rect.top) * photo.h / rect.height);
  if (x < 0 || y < 0 || x >= photo.w || y >= photo.h) return;
  if (R.keyCursor) { R.keyCursor = false; drawAll(); }
  readAt(x, y);
}

// The arrow keys' pixel (keyCursor): read, marked on the frames, and said by the live region.
function keyRead(x, y) {
  if (!R.photo) return;
  R.keyCursor = true;
  readAt(x, y);
  drawAll();
  const focused = R.frames.find((f) => f.canvas === document.activeElement);
  document.getElementById("frame-live").textContent = focused ? focused.readout.textContent : "";
}

function clearReadouts() {
  R.point = null;
  R.frames.forEach((f) => { f.readout.textContent = ""; });
}

// Every frame's readout at pixel (x, y) of the photo shown (image pixels, as drawn).
function readAt(x, y) {
  const photo = R.photo;
  R.point = {x, y};
  const i = y * photo.w + x, p = photo.meta;
  const rgb = (a) => (a ? fmtRGB([a[3 * i], a[3 * i + 1], a[3 * i + 2]], PIXEL_DIGITS) : "   –");
  const col = p.box[2] + x * p.factor, row = p.box[0] + y * p.factor;
  const where = p.factor > 1 ? `(${col}, ${row}) ${p.factor}×${p.factor} mean` : `(${col}, ${row})`;
  for (const f of R.frames) {
    const de = photo.des[f.method];
    f.readout.textContent = `${where}   ΔE ${de ? fmt(de[i], 2) : "–"}\n` +
      `photo  ${rgb(photo.ref)}\nrender ${rgb(photo.renders[f.method])}`;
  }
}

function setFlip(flipped) {
  R.flipped = flipped;
  const button = document.getElementById("flip");
  button.setAttribute("aria-pressed", String(flipped));
  button.textContent = `showing: ${flipped ? "photo" : "render"}`;
  drawAll();
}

function setStops(stops) {
  const input = document.getElementById("exposure");
  const clamped = Math.max(Number(input.min), Math.min(Number(input.max), stops));
  R.stops = Math.round(clamped * 10) / 10;
  input.value = R.stops;
  const text = `${R.stops >= 0 ? "+" : ""}${R.stops.toFixed(1)} EV`;
  document.getElementById("exposure-out").textContent = text;
  input.setAttribute("aria-valuetext", text);
  drawAll();
}

function setOverlay(on) {
  R.overlay = on;
  document.getElementById("overlay").checked = on;
  drawAll();
}

async function showPhoto(index) {
  const count = META.photos.length;
  index = ((index % count) + count) % count;
  R.index = index;
  document.getElementById("photo-select").value = String(index);
  const status = document.getElementById("photo-status");
  status.textContent = `decoding ${META.photos[index].name} …`;
  const photo = await loadPhoto(index);
  if (R.index !== index) return;
  R.photo = photo;
  // the readouts must not keep the photo shown before: read the same pixel of this one
  if (R.point && R.point.x < photo.w && R.point.y < photo.h) readAt(R.point.x, R.point.y);
  else { clearReadouts(); R.keyCursor = false; }
  sizeFrames();  // a photo of another size
  drawAll();
  const p = photo.meta;
  status.textContent = `${p.name}: ${p.width}×${p.height} px shown, the object's box in the ` +
    `${p.full[1]}×${p.full[0]} image` + (p.factor > 1 ? `, downsampled ${p.factor}× (box mean) ` +
    "to keep the page small; the full renders are the EXRs in each method's folder" : "") + ".";
  document.body.dataset.photo = p.name;  // lets tests wait for the frames
  if (!performance.getEntriesByName("first-photo").length) performance.mark("first-photo");
  if (index + 1 < count) loadPhoto(index + 1);  // the next one is likely to be wanted
}

function photoTable() {
  const methods = META.methods;
  const head = el("tr", {}, [el("th", {text: "photo"}), ...methods.map((m) => el("th", {text: m}))]);
  const rows = META.photos.map((p, k) => {
    const values = methods.map((m) => p.delta_e[m]);
    const finite = values.filter(Number.isFinite);
    const best = finite.length ? Math.min(...finite) : NaN;
    return el("tr", {}, [
      el("td", {}, [el("button", {type: "button", text: p.name, onclick: () => showPhoto(k)})]),
      ...values.map((v) => el("td", {text: fmt(v, 2), class: v === best ? "best" : ""}))]);
  });
  document.getElementById("photo-table").append(el("table", {}, [el("thead", {}, [head]),
                                                                 el("tbody", {}, rows)]));
}

function errorsPlot() {
  const canvas = document.getElementById("errors-plot"), photos = META.photos;
  const values = photos.flatMap((p) => Object.values(p.delta_e)).filter(Number.isFinite);
  if (!values.length) { canvas.hidden = true; return; }
  const top = Math.max(...values) * 1.08;
  const ax = new Axes(canvas, {left: 50, top: 26, width: 830, height: 160},
                      {min: -0.5, max: photos.length - 0.5}, {min: 0, max: top});
  const yTicks = linearTicks(top);
  const step = Math.max(1, Math.ceil(photos.length / 20));
  ax.grid(yTicks);
  ax.frame("reference photo (index; hover for its name, click to show it)", "ΔE log mean",
           photos.map((_, k) => k).filter((k) => k % step === 0), yTicks);
  META.methods.forEach((m, s) => {
    ax.ctx.strokeStyle = ax.ctx.fillStyle = METHOD_COLOURS[s % 10];
    ax.ctx.beginPath();
    photos.forEach((p, k) => {
      const v = p.delta_e[m];
      if (!Number.isFinite(v)) return;
      ax.ctx.lineTo(ax.px(k), ax.py(v));
    });
    ax.ctx.globalAlpha = 0.5; ax.ctx.stroke(); ax.ctx.globalAlpha = 1;
    photos.forEach((p, k) => {
      const v = p.delta_e[m];
      if (Number.isFinite(v)) { ax.ctx.beginPath(); ax.ctx.arc(ax.px(k), ax.py(v), 2.5, 0, 7); ax.ctx.fill(); }
    });
  });
  drawLegend(ax.ctx, META.methods.map((m, s) => ({label: m, colour: METHOD_COLOURS[s % 10], dot: true})), 50, 12);
  const pick = (e) => Math.round((ax.eventPoint(e)[0] - ax.box.left) / ax.box.width * photos.length - 0.5);
  canvas.addEventListener("mousemove", (e) => {
    const k = pick(e);
    canvas.title = photos[k] ? `${photos[k].name}: ` + META.methods.map((m) => `${m} ${fmt(photos[k].delta_e[m], 2)}`).join(", ") : "";
  });
  canvas.addEventListener("click", (e) => { const k = pick(e); if (photos[k]) showPhoto(k); });
}

function deColorbar() {
  const bar = document.getElementById("de-colorbar"), gradient = lutGradient("inferno");
  gradient.setAttribute("aria-hidden", "true");
  bar.append(el("span", {text: "0"}), gradient, el("span", {text: `${fmt(META.delta_e_vmax, 1)} ΔE`}));
}

// run's previews (no reference photo, or --envmap): tone-mapped PNGs, no error to show.
function previews() {
  const info = META.previews;
  if (!info || !info.renders.length) return;
  document.getElementById("previews").hidden = false;
  document.getElementById("previews-hint").textContent = `Each method's BRDF under ${info.envmap}, ` +
    "seen from the first flash photo's camera, and on a sphere; tone-mapped (sRGB), no error computed.";
  const grid = document.getElementById("previews-grid");
  for (const r of info.renders) {
    grid.append(el("figure", {}, [el("img", {src: r.src, alt: `${r.method}: ${r.what}`}),
                                 el("figcaption", {text: `${r.method}: ${r.what}`})]));
  }
}

function initRenders() {
  previews();
  if (!META.photos.length) {
    document.getElementById("renders-ui").hidden = true;
    const empty = document.getElementById("renders-empty");
    empty.hidden = false;
    if (META.previews && META.previews.renders.length) {
      empty.textContent = "No reference photo: nothing to compare. The renders under an environment map are below.";
    }
    return;
  }
  const select = document.getElementById("photo-select");
  META.photos.forEach((p, k) => select.append(el("option", {value: String(k), text: p.name})));
  select.addEventListener("change", () => showPhoto(Number(select.value)));
  document.getElementById("photo-prev").addEventListener("click", () => showPhoto(R.index - 1));
  document.getElementById("photo-next").addEventListener("click", () => showPhoto(R.index + 1));
  const exposure = document.getElementById("exposure");
  // ±20 EV, widened to reach every photo's auto exposure (a photo stored in other units)
  const autos = META.photos.map((p) => p.auto_stops).filter(Number.isFinite);
  exposure.min = String(Math.min(-20, Math.floor(Math.min(...autos, 0)) - 5));
  exposure.max = String(Math.max(20, Math.ceil(Math.max(...autos, 0)) + 5));
  exposure.addEventListener("input", () => setStops(Number(exposure.value)));
  document.getElementById("exposure-auto").addEventListener("click",
    () => setStops(META.photos[R.index].auto_stops));
  document.getElementById("flip").addEventListener("click", () => setFlip(!R.flipped));
  const split = document.getElementById("split");
  split.addEventListener("input", () => { R.split = Number(split.value); drawAll(); });
  const overlay = document.getElementById("overlay");
  overlay.addEventListener("change", () => setOverlay(overlay.checked));
  buildFrames();
  window.addEventListener("resize", sizeFrames);
  deColorbar();
  photoTable();
  errorsPlot();
  setStops(R.stops);
  showPhoto(0);
}

// tev's keys where it has one: E / Shift+E exposure ±½ stop, R reset (0 EV), N normalise (here:
// the photo's auto exposure), number keys pick an image (here: one method alone, large).
function rendersKey(event) {
  if (!META.photos.length) return false;
  const k = event.key;
  if (k === "f" || k === "F") setFlip(!R.flipped);
  else if (k === "+" || k === "=" || k === "e") setStops(R.stops + 0.5);
  else if (k === "-" || k === "_" || k === "E") setStops(R.stops - 0.5);
  else if (k === "r" || k === "R") setStops(0);
  else if (k === "0" || k === "n" || k === "N") setStops(META.photos[R.index].auto_stops);
  else if (/^[1-9]$/.test(k) && Number(k) <= META.methods.length) {
    const method = META.methods[Number(k) - 1];
    setSolo(R.solo === method ? null : method);
  } else if (k === "Escape" && R.solo) setSolo(null);
  else if (k === "d" || k === "D") setOverlay(!R.overlay);
  else if (k === "[") showPhoto(R.index - 1);
  else if (k === "]") showPhoto(R.index + 1);
  else return false;
  return true;
}
