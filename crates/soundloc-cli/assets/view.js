// soundloc live view. Everything it draws with (colour map, track colours, azimuth bins,
// scale rule) comes from the server's `hello` message (soundloc::output::style); the
// message formats are documented in soundloc::output::live.
"use strict";

const view = {
  hello: null, // the hello message
  unit: null, // [x, y, z] per direction
  bin: null, // azimuth bin per direction
  binFill: null, // nearest occupied bin per bin
  sky: null, // sphere grids: direction index per sky-map cell
  spectrum: null, // latest Float32Array
  spectrumFrame: -1,
  last: null, // latest result message
  results: 0,
  spectra: 0,
  mins: [],
  maxs: [],
  status: null,
  connected: false,
  dirty: false,
};
window.soundlocView = view;

const $ = (id) => document.getElementById(id);
const rgb = (c) => `rgb(${c[0]},${c[1]},${c[2]})`;
const SKY_W = 180, SKY_H = 90; // sky-map cells: 2° × 2°

function unitOf(azDeg, elDeg) {
  const a = (azDeg * Math.PI) / 180, e = (elDeg * Math.PI) / 180;
  return [Math.cos(e) * Math.cos(a), Math.cos(e) * Math.sin(a), Math.sin(e)];
}

function wrapAz(a) {
  return ((((a + 180) % 360) + 360) % 360) - 180;
}

function setup(h) {
  view.hello = h;
  view.mins = [];
  view.maxs = [];
  view.spectrum = null;
  const az = h.grid.azimuth_deg, el = h.grid.elevation_deg, D = az.length;
  view.unit = az.map((a, d) => unitOf(a, el[d]));
  const nb = Math.round(360 / h.azimuth_bin_deg);
  view.bin = az.map((a) => Math.min(nb - 1, Math.floor((wrapAz(a) + 180) / h.azimuth_bin_deg)));
  const occupied = new Array(nb).fill(false);
  view.bin.forEach((b) => (occupied[b] = true));
  view.binFill = [];
  for (let b = 0; b < nb; b++) {
    let src = b;
    for (let k = 0; k <= nb / 2; k++) {
      if (occupied[(b + k) % nb]) { src = (b + k) % nb; break; }
      if (occupied[(b - k + nb) % nb]) { src = (b - k + nb) % nb; break; }
    }
    view.binFill.push(src);
  }
  if (h.grid.kind === "sphere") {
    // Nearest grid direction of every 2° cell (largest dot product).
    view.sky = new Int32Array(SKY_W * SKY_H);
    for (let r = 0; r < SKY_H; r++) {
      const e = 90 - (r + 0.5) * 2;
      for (let c = 0; c < SKY_W; c++) {
        const u = unitOf(-180 + (c + 0.5) * 2, e);
        let best = 0, bd = -2;
        for (let d = 0; d < D; d++) {
          const v = view.unit[d];
          const dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
          if (dot > bd) { bd = dot; best = d; }
        }
        view.sky[r * SKY_W + c] = best;
      }
    }
  } else {
    view.sky = null;
  }
  $("title").textContent = `— ${h.source}`;
  $("map-caption").textContent = h.grid.kind === "sphere"
    ? "sky map: azimuth (−180° left … 180° right) × elevation (−90° bottom … 90° top)"
    : "ring, seen from above: 0° (+x) up, 90° (+y) left; radius and colour = power";
  const w = $("waterfall");
  w.getContext("2d").clearRect(0, 0, w.width, w.height);
  waterfallAxis();
  view.dirty = true;
}

// Azimuth labels beside the waterfall (its rows: −180° bottom … 180° top).
function waterfallAxis() {
  const a = $("waterfall-axis"), ctx = a.getContext("2d");
  ctx.clearRect(0, 0, a.width, a.height);
  ctx.fillStyle = "#aaa"; ctx.strokeStyle = "#666"; ctx.font = "11px sans-serif";
  ctx.textAlign = "right";
  for (const az of [180, 90, 0, -90, -180]) {
    const y = Math.min(a.height - 6, Math.max(6, a.height - ((az + 180) / 360) * a.height));
    ctx.textBaseline = "middle";
    ctx.fillText(`${az}°`, a.width - 7, y);
    ctx.beginPath(); ctx.moveTo(a.width - 5, y); ctx.lineTo(a.width, y); ctx.stroke();
  }
}

// A label with a dark outline, readable over any colour of the map.
function outlined(ctx, text, x, y, align, baseline) {
  ctx.font = "11px sans-serif"; ctx.textAlign = align; ctx.textBaseline = baseline;
  ctx.lineWidth = 3; ctx.strokeStyle = "rgba(0,0,0,0.85)"; ctx.strokeText(text, x, y);
  ctx.fillStyle = "#ddd"; ctx.fillText(text, x, y);
}

function scale() {
  let lo = Infinity, hi = -Infinity;
  for (const v of view.mins) lo = Math.min(lo, v);
  for (const v of view.maxs) hi = Math.max(hi, v);
  if (!isFinite(lo)) return [0, 1];
  if (hi <= lo) hi = lo + 1;
  return [lo, hi];
}

function colourOf(db, lo, hi) {
  const cm = view.hello.colormap;
  if (!isFinite(db)) return [40, 40, 40];
  const x = Math.min(1, Math.max(0, (db - lo) / (hi - lo)));
  return cm[Math.round(x * (cm.length - 1))];
}

function sourceColour(s) {
  const h = view.hello;
  if (s.id === undefined || s.id === null) return h.peak_colour;
  const n = h.track_colours.length;
  return h.track_colours[((s.id % n) + n) % n];
}

function onSpectrum(buf) {
  const dv = new DataView(buf);
  const magic = String.fromCharCode(dv.getUint8(0), dv.getUint8(1), dv.getUint8(2), dv.getUint8(3));
  if (magic !== "SLSP" || !view.hello) return;
  const frame = Number(dv.getBigUint64(8, true));
  const n = dv.getUint32(20, true);
  const db = new Float32Array(buf, 28, n);
  let lo = Infinity, hi = -Infinity;
  for (const v of db) if (isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  view.mins.push(lo);
  view.maxs.push(hi);
  while (view.mins.length > view.hello.scale_results) { view.mins.shift(); view.maxs.shift(); }
  view.spectrum = db;
  view.spectrumFrame = frame;
  view.spectra++;
  waterfallColumn(db, view.last && view.last.frame === frame ? view.last : null);
  view.dirty = true;
}

function waterfallColumn(db, result) {
  const w = $("waterfall"), ctx = w.getContext("2d");
  const colW = 2, nb = view.binFill.length, bh = w.height / nb;
  ctx.drawImage(w, -colW, 0);
  const binMax = new Float32Array(nb).fill(-Infinity);
  db.forEach((v, d) => { const b = view.bin[d]; if (v > binMax[b]) binMax[b] = v; });
  const [lo, hi] = scale();
  for (let b = 0; b < nb; b++) {
    ctx.fillStyle = rgb(colourOf(binMax[view.binFill[b]], lo, hi));
    ctx.fillRect(w.width - colW, w.height - (b + 1) * bh, colW, Math.ceil(bh));
  }
  if (result) {
    for (const s of result.sources.filter((s) => !s.held)) {
      const y = w.height - ((wrapAz(s.azimuth_deg) + 180) / 360) * w.height;
      ctx.fillStyle = rgb(sourceColour(s));
      ctx.fillRect(w.width - colW - 1, y - 2, colW + 2, 4);
    }
  }
}

function onResult(r) {
  view.last = r;
  view.results++;
  const body = $("peaks").tBodies[0];
  body.innerHTML = "";
  for (const s of r.sources) {
    const tr = document.createElement("tr");
    tr.dataset.azimuth = s.azimuth_deg;
    tr.dataset.elevation = s.elevation_deg;
    tr.dataset.power = s.power_db;
    if (s.id !== undefined) tr.dataset.id = s.id;
    // A tracked source carried through a pause (not observed in this window): dimmed.
    if (s.held) { tr.dataset.held = "1"; tr.className = "held"; }
    const cells = [
      `<span class="swatch" style="background:${rgb(sourceColour(s))}"></span>`,
      s.id === undefined ? "–" : String(s.id) + (s.held ? " (held)" : ""),
      s.azimuth_deg.toFixed(1),
      s.elevation_deg.toFixed(1),
      s.power_db.toFixed(2),
    ];
    tr.innerHTML = cells.map((c) => `<td>${c}</td>`).join("");
    body.appendChild(tr);
  }
  view.dirty = true;
}

function onStatus(s) {
  view.status = s;
  view.dirty = true;
}

function drawStatus() {
  const h = view.hello, s = view.status;
  let t = view.connected ? "" : "disconnected — retrying…  ";
  if (h) t += `${h.label || h.algorithm} on ${h.device} · latency ${h.latency_ms.toFixed(0)} ms`;
  if (s) {
    t += ` · last block ${s.compute_ms.toFixed(2)} ms compute · real-time factor ${s.rtf.toFixed(3)}` +
      ` · ${s.audio_s.toFixed(1)} s localized`;
    if (s.lost_s > 0) t += ` · ${s.lost_s.toFixed(2)} s of input lost`;
    if (s.view_dropped > 0) t += ` · ${s.view_dropped} messages dropped for this page`;
    if (s.finished) t += " · input finished";
  }
  if (view.last) t += ` · frame ${view.last.frame} (${view.last.time_s.toFixed(2)} s)`;
  $("status").textContent = t;
}

function drawSky(ctx, W, H, db, lo, hi) {
  const img = new ImageData(SKY_W, SKY_H);
  for (let i = 0; i < SKY_W * SKY_H; i++) {
    const c = colourOf(db[view.sky[i]], lo, hi);
    img.data[4 * i] = c[0]; img.data[4 * i + 1] = c[1]; img.data[4 * i + 2] = c[2]; img.data[4 * i + 3] = 255;
  }
  const off = document.createElement("canvas");
  off.width = SKY_W; off.height = SKY_H;
  off.getContext("2d").putImageData(img, 0, 0);
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(off, 0, 0, W, H);
  // Canvas pixel of a direction (also used by the browser test).
  view.skyAt = (az, el) => [((wrapAz(az) + 180) / 360) * W, ((90 - el) / 180) * H];
  // Ticks on the edges only (lines across would hide the spectrum): azimuth along the
  // bottom, elevation on the left.
  ctx.strokeStyle = "#ddd"; ctx.lineWidth = 1;
  for (const az of [-180, -90, 0, 90, 180]) {
    const [x] = view.skyAt(az === 180 ? 179.999 : az, 0), xx = az === 180 ? W : x;
    ctx.beginPath(); ctx.moveTo(xx, H); ctx.lineTo(xx, H - 5); ctx.stroke();
    outlined(ctx, `${az}°`, xx, H - 7, az === -180 ? "left" : az === 180 ? "right" : "center", "bottom");
  }
  for (const el of [60, 30, 0, -30, -60]) {
    const [, y] = view.skyAt(0, el);
    ctx.beginPath(); ctx.moveTo(0, y); ctx.lineTo(5, y); ctx.stroke();
    outlined(ctx, `${el}°`, 7, y, "left", "middle");
  }
  return (s) => view.skyAt(s.azimuth_deg, s.elevation_deg);
}

function ringGeometry(W, H) {
  const cx = W / 2, cy = H / 2, R = Math.min(W, H) / 2 - 28, r0 = R * 0.2;
  // Seen from above, +x up, +y left: screen angle of azimuth a.
  const xy = (a, r) => {
    const t = (a * Math.PI) / 180;
    return [cx - r * Math.sin(t), cy - r * Math.cos(t)];
  };
  return { cx, cy, R, r0, xy };
}

function drawRing(ctx, W, H, db, lo, hi) {
  const g = ringGeometry(W, H), az = view.hello.grid.azimuth_deg;
  // Canvas pixel at azimuth a, a fraction f of the way from the inner to the outer radius
  // (also used by the browser test).
  view.ringAt = (a, f) => g.xy(a, g.r0 + (g.R - g.r0) * f);
  const order = az.map((a, d) => [wrapAz(a), d]).sort((p, q) => p[0] - q[0]);
  const n = order.length;
  ctx.strokeStyle = "#333";
  for (const f of [0.25, 0.5, 0.75, 1]) {
    ctx.beginPath(); ctx.arc(g.cx, g.cy, g.r0 + (g.R - g.r0) * f, 0, 2 * Math.PI); ctx.stroke();
  }
  for (let i = 0; i < n; i++) {
    const [a, d] = order[i];
    const prev = i > 0 ? order[i - 1][0] : order[n - 1][0] - 360;
    const next = i + 1 < n ? order[i + 1][0] : order[0][0] + 360;
    const a0 = (a + prev) / 2, a1 = (a + next) / 2;
    const v = db[d], x = Math.min(1, Math.max(0, (v - lo) / (hi - lo)));
    const r = g.r0 + (g.R - g.r0) * (isFinite(x) ? x : 0);
    ctx.fillStyle = rgb(colourOf(v, lo, hi));
    ctx.beginPath();
    const steps = 4;
    for (let k = 0; k <= steps; k++) { const p = g.xy(a0 + ((a1 - a0) * k) / steps, g.r0); k ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1]); }
    for (let k = steps; k >= 0; k--) { const p = g.xy(a0 + ((a1 - a0) * k) / steps, r); ctx.lineTo(p[0], p[1]); }
    ctx.closePath();
    ctx.fill();
  }
  ctx.fillStyle = "#aaa";
  ctx.font = "12px sans-serif";
  ctx.textAlign = "center";
  ctx.textBaseline = "middle";
  for (const a of [0, 90, 180, -90]) { const p = g.xy(a, g.R + 16); ctx.fillText(`${a}°`, p[0], p[1]); }
  return (s) => g.xy(s.azimuth_deg, g.R + 6);
}

function draw() {
  requestAnimationFrame(draw);
  if (!view.dirty) return;
  view.dirty = false;
  drawStatus();
  if (!view.hello || !view.spectrum) return;
  const c = $("map"), ctx = c.getContext("2d");
  ctx.clearRect(0, 0, c.width, c.height);
  const [lo, hi] = scale();
  // Disconnected: the last picture stays, faded, so it is not taken for a live one.
  ctx.globalAlpha = view.connected ? 1 : 0.35;
  const H = c.height - 20, W = view.sky ? 2 * H : c.width;
  const place = view.sky ? drawSky(ctx, W, H, view.spectrum, lo, hi) : drawRing(ctx, W, H, view.spectrum, lo, hi);
  if (view.last) {
    for (const s of view.last.sources) {
      const [x, y] = place(s);
      if (s.held) {
        // Held (carried through a pause, not observed): a dashed outline only.
        ctx.beginPath(); ctx.arc(x, y, view.sky ? 9 : 6, 0, 2 * Math.PI);
        ctx.setLineDash([3, 3]); ctx.strokeStyle = rgb(sourceColour(s)); ctx.lineWidth = 2; ctx.stroke();
        ctx.setLineDash([]);
      } else if (view.sky) {
        // Hollow rings on the sky map: the spectrum under a source stays visible.
        ctx.beginPath(); ctx.arc(x, y, 9, 0, 2 * Math.PI);
        ctx.strokeStyle = "#000"; ctx.lineWidth = 4.5; ctx.stroke();
        ctx.strokeStyle = rgb(sourceColour(s)); ctx.lineWidth = 2.5; ctx.stroke();
      } else {
        ctx.beginPath(); ctx.arc(x, y, 6, 0, 2 * Math.PI);
        ctx.fillStyle = rgb(sourceColour(s)); ctx.fill();
        ctx.strokeStyle = "#fff"; ctx.lineWidth = 1.5; ctx.stroke();
      }
    }
  }
  // Colour bar with the scale's ends.
  for (let i = 0; i < 200; i++) {
    ctx.fillStyle = rgb(colourOf(lo + ((hi - lo) * i) / 199, lo, hi));
    ctx.fillRect(10 + i, c.height - 14, 1, 10);
  }
  ctx.fillStyle = "#ccc"; ctx.font = "11px sans-serif"; ctx.textAlign = "left"; ctx.textBaseline = "middle";
  ctx.fillText(`${lo.toFixed(1)} … ${hi.toFixed(1)} dB`, 216, c.height - 9);
  ctx.globalAlpha = 1;
}

function connect() {
  const ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = "arraybuffer";
  ws.onopen = () => { view.connected = true; view.dirty = true; };
  ws.onclose = () => { view.connected = false; view.dirty = true; setTimeout(connect, 1000); };
  ws.onmessage = (ev) => {
    if (typeof ev.data !== "string") return onSpectrum(ev.data);
    const m = JSON.parse(ev.data);
    if (m.type === "hello") setup(m);
    else if (m.type === "result") onResult(m);
    else if (m.type === "status") onStatus(m);
  };
}

connect();
requestAnimationFrame(draw);
