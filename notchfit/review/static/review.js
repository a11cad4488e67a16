// notchfit review: the page. Plain JavaScript, no build step, no external files.
// The image is drawn from a pyramid of JPEG tiles (level 0 = full resolution, each next level
// half the size): the level that matches the zoom, over the coarsest level as a backdrop.
"use strict";

const COLORS = { ok: "#2ca02c", ambiguous: "#ff9f1c", manual: "#1f9bde" };
const HIT_PX = 9;          // a press this close to a corner grabs it [screen px]
const CLICK_PX = 4;        // a press that moves less is a click, not a drag [screen px]
const POLL_MS = 1500;      // how often the page asks for other tabs' changes
const MISSING = ["missing", "deleted", "occluded"];

const S = {
  client: Math.random().toString(36).slice(2) + Date.now().toString(36),
  study: null, exp: 0, sample: null, data: null, fit: null, angles: null, selected: null,
  mode: "corners", undo: [], seq: 0, view: { scale: 1, ox: 0, oy: 0 }, tiles: new Map(),
  drag: null, ready: false, timings: [], switchStart: null, pollPaused: false, thumbsOn: false,
};
window.review = S;          // for the browser tests: state, timings, coordinate helpers

const $ = (id) => document.getElementById(id);
const canvas = $("canvas");
const ctx = canvas.getContext("2d");

// ------------------------------------------------------------------------------ server
async function api(path, body) {
  const opts = body === undefined ? {} : { method: "POST", headers: { "Content-Type": "application/json" },
    body: JSON.stringify(body) };
  const r = await fetch(path, opts);
  const out = await r.json();
  if (!r.ok) throw new Error(out.error || r.statusText);
  return out;
}

function say(text, conflict) {
  const m = $("message");
  m.textContent = text;
  m.className = conflict ? "conflict" : "";
}

// ------------------------------------------------------------------------------ study and strip
async function loadStudy() {
  S.study = await api("/api/study");
  S.seq = S.study.seq;
  const sel = $("exp");
  sel.innerHTML = "";
  S.study.experiments.forEach((e) => {
    const o = document.createElement("option");
    o.value = e.index; o.textContent = `${e.name} (${e.samples.length})`;
    sel.appendChild(o);
  });
}

function experiment() { return S.study.experiments[S.exp]; }

function badness(c) { return c.missing * 2 + c.ambiguous; }

function orderedSamples() {
  const list = experiment().samples.slice();
  if ($("worst").checked) list.sort((a, b) => badness(b.counts) - badness(a.counts) || a.sample - b.sample);
  return list;
}

function countsHtml(c) {
  return `<span class="c-ok" title="ok">${c.ok}</span><span class="c-amb" title="ambiguous">${c.ambiguous}</span>` +
    `<span class="c-miss" title="missing">${c.missing}</span>`;
}

function renderStrip() {
  const strip = $("strip");
  strip.innerHTML = "";
  for (const s of orderedSamples()) {
    const d = document.createElement("div");
    d.className = "thumb" + (s.sample === S.sample ? " current" : "");
    d.dataset.sample = s.sample;
    // thumbnails are asked for once the photograph is drawn: they never delay it
    const src = `/api/thumb/${S.exp}/${s.sample}.jpg`;
    const img = s.image ? `<img loading="lazy" alt="" ${S.thumbsOn ? "src" : "data-src"}="${src}">` : "<img alt=''>";
    d.innerHTML = `${img}<div class="name">sample ${s.sample}</div><div class="counts">${countsHtml(s.counts)}</div>`;
    d.onclick = () => openSample(s.sample);
    strip.appendChild(d);
  }
  const cur = strip.querySelector(".current");
  if (cur) cur.scrollIntoView({ block: "nearest", inline: "nearest" });
}

function setCounts(sample, counts) {
  const s = experiment().samples.find((x) => x.sample === sample);
  if (!s) return;
  s.counts = counts;
  const el = $("strip").querySelector(`.thumb[data-sample="${sample}"] .counts`);
  if (el) el.innerHTML = countsHtml(counts);
}

// ------------------------------------------------------------------------------ one sample
async function openSample(sample, keepView) {
  S.switchStart = performance.now();
  S.ready = false;
  const data = await api(`/api/sample/${S.exp}/${sample}`);
  const sameImage = keepView && S.data && S.data.sample === sample;
  S.sample = sample; S.data = data;
  if (!sameImage) { S.tiles = new Map(); S.selected = null; S.fit = null; S.angles = null; fitToWindow(); }
  $("where").textContent = `${experiment().name}, sample ${sample}`;
  renderStrip();
  renderPanel();
  draw();
  refreshMeasures();
}

function corner(point) { return S.data.corners[point - 1]; }

function step(delta) {
  const list = orderedSamples();
  const i = list.findIndex((s) => s.sample === S.sample);
  const j = Math.min(list.length - 1, Math.max(0, i + delta));
  if (j !== i) openSample(list[j].sample);
}

// ------------------------------------------------------------------------------ view
function resize() {
  const r = canvas.getBoundingClientRect();
  const dpr = window.devicePixelRatio || 1;
  canvas.width = Math.round(r.width * dpr); canvas.height = Math.round(r.height * dpr);
  ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  draw();
}

function fitToWindow() {
  // the whole photograph, or without one the box around the corners
  const r = canvas.getBoundingClientRect();
  let box = null;
  if (S.data && S.data.image) box = [-0.5, -0.5, S.data.image.width - 0.5, S.data.image.height - 0.5];
  else if (S.data) {
    const cs = S.data.corners.filter((c) => c.u !== null);
    if (cs.length) {
      const us = cs.map((c) => c.u), vs = cs.map((c) => c.v);
      box = [Math.min(...us) - 20, Math.min(...vs) - 20, Math.max(...us) + 20, Math.max(...vs) + 20];
    }
  }
  if (!box) { S.view = { scale: 1, ox: 0, oy: 0 }; return; }
  const w = box[2] - box[0], h = box[3] - box[1];
  const scale = Math.min(r.width / w, r.height / h) * 0.98;
  S.view = { scale, ox: (box[0] + box[2]) / 2 - r.width / 2 / scale, oy: (box[1] + box[3]) / 2 - r.height / 2 / scale };
}

function toScreen(u, v) { return [(u - S.view.ox) * S.view.scale, (v - S.view.oy) * S.view.scale]; }
function toImage(x, y) { return [x / S.view.scale + S.view.ox, y / S.view.scale + S.view.oy]; }
S.toScreen = toScreen;
S.toImage = toImage;

function zoomAt(x, y, factor) {
  const [u, v] = toImage(x, y);
  S.view.scale = Math.min(16, Math.max(0.01, S.view.scale * factor));
  S.view.ox = u - x / S.view.scale; S.view.oy = v - y / S.view.scale;
  draw();
}

// ------------------------------------------------------------------------------ tiles
function tile(level, tx, ty) {
  const key = `${S.exp}/${S.sample}/${level}/${tx}/${ty}`;
  let t = S.tiles.get(key);
  if (!t) {
    t = new Image();
    t.onload = () => draw();
    t.src = `/api/tile/${key}.jpg`;
    S.tiles.set(key, t);
  }
  return t;
}

function drawLevel(level, visibleOnly) {
  const im = S.data.image;
  const [lw, lh] = im.levels[level];
  const f = im.width / lw;                 // image pixels per level pixel
  const T = im.tile;
  const r = canvas.getBoundingClientRect();
  const [u0, v0] = toImage(0, 0), [u1, v1] = toImage(r.width, r.height);
  const tx0 = visibleOnly ? Math.max(0, Math.floor((u0 + 0.5) / f / T)) : 0;
  const ty0 = visibleOnly ? Math.max(0, Math.floor((v0 + 0.5) / f / T)) : 0;
  const tx1 = Math.min(Math.ceil(lw / T) - 1, visibleOnly ? Math.floor((u1 + 0.5) / f / T) : 1e9);
  const ty1 = Math.min(Math.ceil(lh / T) - 1, visibleOnly ? Math.floor((v1 + 0.5) / f / T) : 1e9);
  let complete = true;
  for (let ty = ty0; ty <= ty1; ty++) {
    for (let tx = tx0; tx <= tx1; tx++) {
      const t = tile(level, tx, ty);
      if (!t.complete || !t.naturalWidth) { complete = false; continue; }
      // level pixel (i, j) covers image pixels [i f - 0.5, (i + 1) f - 0.5) (pixel centres at integers)
      const [x, y] = toScreen(tx * T * f - 0.5, ty * T * f - 0.5);
      ctx.drawImage(t, x, y, t.naturalWidth * f * S.view.scale, t.naturalHeight * f * S.view.scale);
    }
  }
  return complete;
}

function chooseLevel() {
  const im = S.data.image;
  const dpr = window.devicePixelRatio || 1;
  let level = Math.floor(Math.log2(1 / (S.view.scale * dpr)));
  return Math.min(im.levels.length - 1, Math.max(0, level));
}

// ------------------------------------------------------------------------------ drawing
let pending = false;
function draw() {
  if (pending) return;
  pending = true;
  requestAnimationFrame(() => { pending = false; paint(); });
}

function paint() {
  const r = canvas.getBoundingClientRect();
  ctx.clearRect(0, 0, r.width, r.height);
  if (!S.data) return;
  let complete = true;
  if (S.data.image) {
    const top = S.data.image.levels.length - 1;
    const backdrop = drawLevel(top, false);
    const level = chooseLevel();
    complete = (level === top ? backdrop : drawLevel(level, true)) && backdrop;
  }
  drawOverlay();
  if (complete && !S.ready && S.switchStart !== null) {
    S.ready = true;
    // ms: from asking for the sample to its image and corners drawn; at: since the page was opened
    S.timings.push({ sample: S.sample, ms: performance.now() - S.switchStart, at: performance.now() });
    S.switchStart = null;
    if (!S.thumbsOn) {
      S.thumbsOn = true;
      document.querySelectorAll("#strip img[data-src]").forEach((im) => { im.src = im.dataset.src; });
    }
  }
}

function residualBad(q) {
  const f = S.fit;
  if (!f || !f.ok) return false;
  const e = f.residual_mm[q - 1], c = corner(q);
  // 4 σ: a correct corner's distance (Rayleigh) passes it once in 3000, i.e. in one sample of 50
  return e !== null && c.sigma_mm && e > 4 * Math.max(c.sigma_mm, 1e-6) && e > 3 * f.rms_mm;
}

function drawOverlay() {
  const cs = S.data.corners;
  // the outline through the corners, in their numbering (anticlockwise around the tube)
  ctx.lineWidth = 1.5; ctx.strokeStyle = "rgba(255, 230, 80, 0.75)";
  ctx.beginPath();
  for (let k = 0; k <= cs.length; k++) {
    const a = cs[k % cs.length], b = cs[(k + 1) % cs.length];
    if (k === cs.length || a.u === null || b.u === null) continue;
    const [x0, y0] = toScreen(a.u, a.v), [x1, y1] = toScreen(b.u, b.v);
    ctx.moveTo(x0, y0); ctx.lineTo(x1, y1);
  }
  ctx.stroke();
  if (S.mode === "angles") drawFaces();
  drawPredicted();
  ctx.font = "11px system-ui, sans-serif";
  for (const c of cs) {
    if (c.u === null) continue;
    const [x, y] = toScreen(c.u, c.v);
    ctx.beginPath(); ctx.arc(x, y, 5, 0, 2 * Math.PI);
    ctx.fillStyle = COLORS[c.status] || "#888"; ctx.fill();
    ctx.lineWidth = c.point === S.selected ? 3 : 1; ctx.strokeStyle = c.point === S.selected ? "#fff" : "#000";
    ctx.stroke();
    if (residualBad(c.point)) {
      ctx.beginPath(); ctx.arc(x, y, 10, 0, 2 * Math.PI); ctx.lineWidth = 2; ctx.strokeStyle = "#ff3030"; ctx.stroke();
    }
    ctx.fillStyle = "#fff"; ctx.strokeStyle = "#000"; ctx.lineWidth = 3;
    ctx.strokeText(String(c.point), x + 7, y - 6); ctx.fillText(String(c.point), x + 7, y - 6);
  }
}

function drawPredicted() {
  // where the fit puts the selected missing corner: a hollow ring to click near
  const f = S.fit;
  if (!f || !f.predicted_px || S.selected === null) return;
  const c = corner(S.selected);
  if (c.u !== null) return;
  const p = f.predicted_px[S.selected - 1];
  if (!p || p[0] === null) return;
  const [x, y] = toScreen(p[0], p[1]);
  ctx.setLineDash([3, 3]); ctx.lineWidth = 2; ctx.strokeStyle = "#ff5050";
  ctx.beginPath(); ctx.arc(x, y, 8, 0, 2 * Math.PI); ctx.stroke(); ctx.setLineDash([]);
}

function drawFaces() {
  const a = S.angles;
  if (!a) return;
  ctx.lineWidth = 2; ctx.strokeStyle = "#ff4fd8"; ctx.fillStyle = "#ff9fe9"; ctx.font = "12px system-ui, sans-serif";
  a.faces.forEach((pair, j) => {
    if (!pair) return;
    for (const seg of pair) {
      const [x0, y0] = toScreen(seg[0][0], seg[0][1]), [x1, y1] = toScreen(seg[1][0], seg[1][1]);
      ctx.beginPath(); ctx.moveTo(x0, y0); ctx.lineTo(x1, y1); ctx.stroke();
    }
    const th = a.theta_deg[j];
    if (th !== null) {
      // the label beyond the faces' inner ends, outlined so that it reads on any background
      const mid = (k) => (pair[0][k][0] + pair[1][k][0]) / 2, midv = (k) => (pair[0][k][1] + pair[1][k][1]) / 2;
      const [x0, y0] = toScreen(mid(0), midv(0)), [x1, y1] = toScreen(mid(1), midv(1));
      const len = Math.hypot(x1 - x0, y1 - y0) || 1;
      const x = x1 + (x1 - x0) / len * 14, y = y1 + (y1 - y0) / len * 14;
      const text = `${j + 1}: ${th.toFixed(2)}°`;
      ctx.textAlign = "center"; ctx.textBaseline = "middle";
      ctx.lineWidth = 3; ctx.strokeStyle = "#000"; ctx.strokeText(text, x, y); ctx.fillText(text, x, y);
      ctx.textAlign = "start"; ctx.textBaseline = "alphabetic"; ctx.lineWidth = 2; ctx.strokeStyle = "#ff4fd8";
    }
  });
}

// ------------------------------------------------------------------------------ panel
function renderPanel() {
  const c = S.selected === null ? null : corner(S.selected);
  $("corner-id").textContent = c ? c.point : "–";
  if (c) {
    const pos = c.u === null ? "no position" : `u ${c.u.toFixed(1)}, v ${c.v.toFixed(1)} px`;
    const sig = c.sigma_mm ? `, σ ${(c.sigma_mm * 1000).toFixed(1)} µm` : "";
    $("corner-info").innerHTML = `<span class="st-${c.status}">${c.status}</span> (detected: ${c.detected})` +
      `<br>${pos}${sig}` + (c.u === null ? "<br>click on the image to place it" : "");
  } else {
    $("corner-info").textContent = "Click a corner to select it.";
  }
  $("viewer").classList.toggle("placing", !!(c && c.u === null));
  const miss = S.data.corners.filter((x) => x.u === null);
  $("missing").innerHTML = miss.length ? "missing: " : "";
  for (const m of miss) {
    const b = document.createElement("button");
    b.textContent = m.point; b.className = m.point === S.selected ? "sel" : "";
    b.onclick = () => select(m.point);
    $("missing").appendChild(b);
  }
  renderFit();
  renderAngles();
}

function renderFit() {
  const f = S.fit, body = $("fit-table").tBodies[0];
  body.innerHTML = "";
  if (!f) { $("fit-summary").textContent = "fitting…"; return; }
  if (!f.ok && f.rms_mm === null) { $("fit-summary").textContent = f.message; return; }
  $("fit-summary").innerHTML = `rms ${(f.rms_mm * 1000).toFixed(1)} µm, χ²/dof ${f.chi2_dof.toFixed(2)}` +
    ` (${f.used.filter(Boolean).length} corners fitted)<br><small>${f.message}</small>`;
  const max = Math.max(...f.residual_mm.filter((e) => e !== null));
  // worst first: the corner the fit disagrees with most heads the table
  const order = S.data.corners.map((c, i) => i).filter((i) => f.residual_mm[i] !== null)
    .sort((i, j) => f.residual_mm[j] - f.residual_mm[i]);
  order.forEach((i) => {
    const c = S.data.corners[i], e = f.residual_mm[i];
    const tr = document.createElement("tr");
    tr.className = (c.point === S.selected ? "sel " : "") + (residualBad(c.point) ? "bad" : "");
    tr.dataset.point = c.point;
    tr.innerHTML = `<td>${c.point}</td><td class="st-${c.status}">${c.status}</td><td>${(e * 1000).toFixed(1)} µm</td>` +
      `<td style="text-align:left"><span class="bar" style="width:${Math.round(60 * e / max)}px"></span></td>`;
    tr.onclick = () => select(c.point);
    body.appendChild(tr);
  });
}

function renderAngles() {
  $("angles-box").hidden = S.mode !== "angles";
  const body = $("angles-table").tBodies[0];
  body.innerHTML = "";
  if (!S.angles) return;
  S.angles.theta_deg.forEach((t, j) => {
    const tr = document.createElement("tr");
    tr.innerHTML = `<td>${j + 1}</td><td>${t === null ? "–" : t.toFixed(3)}</td>`;
    body.appendChild(tr);
  });
}

let measureTimer = null;
function refreshMeasures() {
  clearTimeout(measureTimer);
  measureTimer = setTimeout(async () => {
    const want = [S.exp, S.sample];
    const fit = await api(`/api/fit/${S.exp}/${S.sample}`);
    const angles = S.mode === "angles" ? await api(`/api/angles/${S.exp}/${S.sample}`) : null;
    if (want[0] !== S.exp || want[1] !== S.sample) return;
    S.fit = fit; S.angles = angles;
    renderPanel(); draw();
  }, 60);
}

function select(point) {
  S.selected = point;
  const c = corner(point);
  if (c.u === null && S.fit && S.fit.predicted_px && S.fit.predicted_px[point - 1][0] !== null) {
    const p = S.fit.predicted_px[point - 1], r = canvas.getBoundingClientRect();
    const [x, y] = toScreen(p[0], p[1]);
    if (x < 0 || y < 0 || x > r.width || y > r.height) {
      S.view.ox = p[0] - r.width / 2 / S.view.scale; S.view.oy = p[1] - r.height / 2 / S.view.scale;
    }
  }
  renderPanel(); draw();
}

// ------------------------------------------------------------------------------ edits
async function edit(point, action, extra, noUndo) {
  const c = corner(point);
  const before = { exp: S.exp, sample: S.sample, point, row: c.review };
  const body = Object.assign({ exp: S.exp, sample: S.sample, point, action, version: c.version, client: S.client },
    extra || {});
  try {
    const out = await api("/api/edit", body);
    if (!noUndo) S.undo.push(before);
    if (before.exp === S.exp && before.sample === S.sample) S.data.corners[point - 1] = out.corner;
    // a corner just deleted or marked occluded is let go: the next click must not place it again
    if ((action === "delete" || action === "occlude") && S.selected === point) S.selected = null;
    S.seq = Math.max(S.seq, out.seq);
    setCounts(before.sample, out.counts);
    say(out.conflict || `corner ${point}: ${action} (saved to review.csv)`, !!out.conflict);
    renderPanel(); draw(); refreshMeasures();
  } catch (err) {
    say(`not saved: ${err.message}`, true);
    if (before.exp === S.exp && before.sample === S.sample) openSample(S.sample, true);   // show what is saved
  }
}

async function undo() {
  const last = S.undo.pop();
  if (!last) { say("nothing to undo"); return; }
  if (last.exp !== S.exp) { S.exp = last.exp; $("exp").value = last.exp; }
  if (last.sample !== S.sample) await openSample(last.sample);
  await edit(last.point, "restore", { row: last.row }, true);
  say(`undone: corner ${last.point}`);
}

function nextMissing() {
  const miss = S.data.corners.filter((c) => c.u === null).map((c) => c.point);
  if (!miss.length) { say("no missing corner in this sample"); return; }
  const next = miss.find((p) => S.selected === null || p > S.selected) || miss[0];
  select(next);
}

// ------------------------------------------------------------------------------ other tabs
async function poll() {
  // pollPaused: a tab that has not heard of the others yet (a background tab the browser throttles; the tests)
  if (S.pollPaused) { setTimeout(poll, POLL_MS); return; }
  try {
    const out = await api(`/api/changes?since=${S.seq}&client=${encodeURIComponent(S.client)}`);
    S.seq = out.seq;
    let touched = false;
    for (const ch of out.changes) {
      say(`corner ${ch.point} of sample ${ch.sample} was changed in another tab`, true);
      if (ch.exp === S.exp && ch.sample === S.sample && S.data) {
        S.data.corners[ch.point - 1] = ch.corner; touched = true;
      }
    }
    if (out.changes.length) {
      const fresh = await api("/api/study");
      S.study.experiments.forEach((e, k) => { e.samples = fresh.experiments[k].samples; });
      renderStrip();
    }
    if (touched) { renderPanel(); draw(); refreshMeasures(); }
  } catch (err) { /* the server is gone: keep the page */ }
  setTimeout(poll, POLL_MS);
}

// ------------------------------------------------------------------------------ mouse and keys
function hit(x, y) {
  let best = null, bestD = HIT_PX;
  for (const c of S.data.corners) {
    if (c.u === null) continue;
    const [cx, cy] = toScreen(c.u, c.v);
    const d = Math.hypot(cx - x, cy - y);
    if (d < bestD) { best = c.point; bestD = d; }
  }
  return best;
}

function local(ev) { const r = canvas.getBoundingClientRect(); return [ev.clientX - r.left, ev.clientY - r.top]; }

canvas.addEventListener("mousedown", (ev) => {
  if (!S.data) return;
  const [x, y] = local(ev);
  const p = hit(x, y);
  S.drag = { x, y, point: p, moved: false, ox: S.view.ox, oy: S.view.oy };
});
window.addEventListener("mousemove", (ev) => {
  const d = S.drag;
  if (!d) return;
  const [x, y] = local(ev);
  if (Math.hypot(x - d.x, y - d.y) > CLICK_PX) d.moved = true;
  if (!d.moved) return;
  if (d.point !== null) {
    const c = corner(d.point);
    [c.u, c.v] = toImage(x, y);
  } else {
    S.view.ox = d.ox - (x - d.x) / S.view.scale; S.view.oy = d.oy - (y - d.y) / S.view.scale;
  }
  draw();
});
window.addEventListener("mouseup", (ev) => {
  const d = S.drag;
  S.drag = null;
  if (!d || !S.data) return;
  const [x, y] = local(ev);
  const [u, v] = toImage(x, y);
  if (d.point !== null && d.moved) {
    select(d.point);
    edit(d.point, "move", { u, v });
  } else if (!d.moved && S.selected !== null && corner(S.selected).u === null) {
    edit(S.selected, "place", { u, v });           // a click places the selected missing corner
  } else if (!d.moved && d.point !== null) {
    select(d.point);
  }
});
canvas.addEventListener("wheel", (ev) => {
  ev.preventDefault();
  const [x, y] = local(ev);
  zoomAt(x, y, Math.exp(-ev.deltaY * 0.0015));
}, { passive: false });

window.addEventListener("keydown", (ev) => {
  if (ev.target.tagName === "SELECT" || ev.target.tagName === "INPUT") return;
  const k = ev.key.toLowerCase();
  const sel = S.selected;
  if (k === "n" || k === "arrowright") step(1);
  else if (k === "p" || k === "arrowleft") step(-1);
  else if (k === "m") nextMissing();
  else if (k === "z") undo();
  else if (k === "f") { fitToWindow(); draw(); }
  else if (k === "g") setMode(S.mode === "angles" ? "corners" : "angles");
  else if (sel !== null && (k === "delete" || k === "backspace")) edit(sel, "delete");
  else if (sel !== null && k === "o") edit(sel, "occlude");
  else if (sel !== null && k === "a") edit(sel, "accept");
  else if (sel !== null && k === "r") edit(sel, "revert");
  else return;
  ev.preventDefault();
});

function setMode(mode) {
  S.mode = mode;
  document.querySelectorAll("input[name=mode]").forEach((r) => { r.checked = r.value === mode; });
  renderPanel(); refreshMeasures(); draw();
}

$("b-delete").onclick = () => S.selected !== null && edit(S.selected, "delete");
$("b-occlude").onclick = () => S.selected !== null && edit(S.selected, "occlude");
$("b-accept").onclick = () => S.selected !== null && edit(S.selected, "accept");
$("b-revert").onclick = () => S.selected !== null && edit(S.selected, "revert");
$("b-undo").onclick = () => undo();
$("b-write-angles").onclick = async () => {
  try {
    const out = await api(`/api/angles/${S.exp}`, {});
    $("angles-note").textContent = `${out.measured} of ${out.total} angles written to ${out.path}`;
  } catch (err) { say(`not written: ${err.message}`, true); }
};
document.querySelectorAll("input[name=mode]").forEach((r) => { r.onchange = () => setMode(r.value); });
$("worst").onchange = () => renderStrip();
$("exp").onchange = () => { S.exp = Number($("exp").value); openSample(experiment().samples[0].sample); };
window.addEventListener("resize", resize);

(async function start() {
  await loadStudy();
  resize();
  const first = experiment().samples[0];
  if (first) await openSample(first.sample);
  setTimeout(poll, POLL_MS);
})();
