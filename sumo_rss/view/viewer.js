// sumo-rss view: replays one run or audit top-down, with its RSS danger episodes on top.
// `sumo-rss view` embeds this module with a JSON header (tables) and a gzip'ed blob of typed arrays (what is drawn
// per step; layout: sumo_rss/view/payload.py). World coordinates are metres relative to header.origin, y up.

const $ = (id) => document.getElementById(id);

const COLOUR = {
  ground: "#eeeeea", road: "#5c5c5c", junction: "#676767", sidewalk: "#b4b4ae", bicycle: "#a0705e", crossing: "#5c5c5c",
  walkingarea: "#b4b4ae", rail: "#8a8170", marking: "#ffffff", car: "#9db8d9", ego: "#1a9850",
  outline: "#24323f", amber: "#f59e0b", red: "#dc2626", selected: "#7c3aed", crash: "#000000", grid: "#e3e3e3",
};
const SIGNAL = { G: "#00b300", g: "#00e000", y: "#ffd000", Y: "#ffd000", u: "#ff9000", r: "#e00000", R: "#e00000",
  o: "#805000", O: "#909090", s: "#8000a0" };
const MAX_LIST_ROWS = 1000;  // rows of the episode list shown at once (sort or filter to reach the others)
const COLLISION_SHOWN_S = 3;  // [s] how long a collision stays marked

// ---- data -------------------------------------------------------------------------------------------------------
async function inflate(id) {
  const text = atob(document.getElementById(id).textContent.trim());
  const bytes = new Uint8Array(text.length);
  for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
  return new Response(new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"))).arrayBuffer();
}

// The blob's arrays (layout: sumo_rss/view/blob.py): values gathered back from their byte planes, differences along
// a key array summed up, quantised values scaled (the type's minimum: NaN).
const TYPES = { f8: Float64Array, f4: Float32Array, i4: Int32Array, u4: Uint32Array, i2: Int16Array, u2: Uint16Array,
  u1: Uint8Array };
function gather(buffer, type, offset, n) {
  const T = TYPES[type], size = T.BYTES_PER_ELEMENT, p = new Uint8Array(buffer, offset, n * size), out = new T(n);
  if (size === 1) out.set(p);
  else if (size === 2) for (let i = 0; i < n; i++) out[i] = p[i] | (p[n + i] << 8);
  else if (type[0] !== "f") for (let i = 0; i < n; i++) out[i] = p[i] | (p[n + i] << 8) | (p[2 * n + i] << 16) | (p[3 * n + i] << 24);
  else {
    const bytes = new Uint8Array(out.buffer);
    for (let b = 0; b < size; b++) for (let i = 0, j = b; i < n; i++, j += size) bytes[j] = p[b * n + i];
  }
  return out;
}

function arrays(buffer, index) {
  const out = {};
  for (const [name, [type, offset, length, options]] of Object.entries(index)) {
    const values = gather(buffer, type, offset, length);
    if (options.delta_by) {
      const key = out[options.delta_by], last = new Int32Array(key.reduce((m, k) => Math.max(m, k), 0) + 1).fill(-1);
      for (let i = 0; i < length; i++) {
        if (last[key[i]] >= 0) values[i] += values[last[key[i]]];
        last[key[i]] = i;
      }
    }
    if (options.unit === undefined) { out[name] = values; continue; }
    const missing = type === "i2" ? -32768 : -2147483648, scaled = new Float32Array(length);
    for (let i = 0; i < length; i++) scaled[i] = values[i] === missing ? NaN : values[i] * options.unit;
    out[name] = scaled;
  }
  return out;
}

const timings = { start: performance.now() };  // [ms since navigation] when each loading stage ended
const header = JSON.parse(document.getElementById("header").textContent);
timings.header = performance.now();
const A = arrays(await inflate("scene-blob"), header.scene_blob);  // the episodes' states follow the first frame
timings.scene = performance.now();
const time = A.time, steps = time.length;
const veh = header.vehicles, nVehicles = veh.ids.length;
const egoClass = veh.classes.indexOf("ego");
const ep = header.episodes, nEpisodes = ep.episode_key.length;
const HEADING = Math.PI / 32767;
let nStates = 0;  // per-car state arrays: car a's nStates values, then car b's (0 until they are read)

// Per episode: from when each car is responsible (its first violation), and its violation intervals.
const blameFrom = Array.from({ length: nEpisodes }, () => [Infinity, Infinity]);
const violating = Array.from({ length: nEpisodes }, () => []);
header.violations.episode.forEach((e, i) => {
  if (e < 0) return;
  const side = header.violations.side[i], t0 = header.violations.t_start_s[i];
  blameFrom[e][side] = Math.min(blameFrom[e][side], t0);
  violating[e].push([side, t0, header.violations.t_end_s[i]]);
});
const signalChanges = header.signals.ids.map(() => ({ time: [], state: [] }));
header.signals.time.forEach((t, i) => {
  const s = signalChanges[header.signals.signal[i]];
  s.time.push(t); s.state.push(header.signals.state[i]);
});

function lastAtOrBefore(values, t) {  // index of the last value <= t (values ascending), -1 if none
  let lo = 0, hi = values.length;
  while (lo < hi) { const mid = (lo + hi) >> 1; if (values[mid] <= t + 1e-9) lo = mid + 1; else hi = mid; }
  return lo - 1;
}
const stepAt = (t) => Math.max(0, lastAtOrBefore(time, t));

// ---- state ------------------------------------------------------------------------------------------------------
const view = { scale: 3, cx: 0, cy: 0 };  // px per m, world point at the canvas centre
const state = { time: steps ? time[0] : 0, step: 0, playing: false, speed: 1, episode: -1, picked: -1, follow: -1,
  wall: null, dirty: true, shownStep: -1 };
const stats = { frames: 0, renderMs: [] };
const scene = $("scene"), ctx = scene.getContext("2d", { alpha: false });
let frame = null;

// The vehicles at `t`: each recorded one's front-bumper centre and heading, interpolated between the two steps
// around t where the vehicle is in both.
const slotOf = new Int32Array(nVehicles).fill(-1);
const nextRow = new Int32Array(nVehicles).fill(-1);
function vehiclesAt(t) {
  if (frame) for (let i = 0; i < frame.n; i++) slotOf[frame.veh[i]] = -1;
  const k = stepAt(t), s = A.step_start[k], n = A.step_start[k + 1] - s;
  const f = { k, n, veh: A.vehicle.subarray(s, s + n), x: new Float32Array(n), y: new Float32Array(n),
    h: new Float32Array(n), speed: new Float32Array(n) };
  const u = k + 1 < steps && time[k + 1] > time[k] ? Math.min(1, Math.max(0, (t - time[k]) / (time[k + 1] - time[k]))) : 0;
  const s1 = k + 1 < steps ? A.step_start[k + 1] : 0, e1 = k + 1 < steps ? A.step_start[k + 2] : 0;
  if (u > 0) for (let r = s1; r < e1; r++) nextRow[A.vehicle[r]] = r;
  for (let i = 0; i < n; i++) {
    const r = s + i, v = f.veh[i], q = u > 0 ? nextRow[v] : -1;
    let x = A.x[r] * 0.01, y = A.y[r] * 0.01, h = A.heading[r] * HEADING;
    if (q >= 0) {
      x += (A.x[q] * 0.01 - x) * u; y += (A.y[q] * 0.01 - y) * u;
      let dh = A.heading[q] * HEADING - h;
      dh -= 2 * Math.PI * Math.round(dh / (2 * Math.PI));
      h += dh * u;
    }
    f.x[i] = x; f.y[i] = y; f.h[i] = h; f.speed[i] = A.speed[r] * 0.01;
    slotOf[v] = i;
  }
  if (u > 0) for (let r = s1; r < e1; r++) nextRow[A.vehicle[r]] = -1;
  return f;
}

function centre(f, i) {  // geometric centre of the vehicle in slot i
  const half = A.length[f.veh[i]] / 2;
  return [f.x[i] - half * Math.cos(f.h[i]), f.y[i] - half * Math.sin(f.h[i])];
}

// ---- network ----------------------------------------------------------------------------------------------------
function addLine(path, xy, first, end, closed) {  // points first..end-1 of a point array
  path.moveTo(xy[2 * first], xy[2 * first + 1]);
  for (let i = first + 1; i < end; i++) path.lineTo(xy[2 * i], xy[2 * i + 1]);
  if (closed) path.closePath();
}

function buildNetwork() {
  const groups = new Map();  // "kind|width" → one path of those lanes
  for (let k = 0; k + 1 < A.lane_start.length; k++) {
    const kind = header.lane_kinds[A.lane_kind[k]], key = `${kind}|${A.lane_width[k].toFixed(2)}`;
    if (!groups.has(key)) groups.set(key, { kind, width: A.lane_width[k], path: new Path2D() });
    addLine(groups.get(key).path, A.lane_xy, A.lane_start[k], A.lane_start[k + 1], kind === "walkingarea");
  }
  const junctions = new Path2D(), markings = new Path2D();
  const starts = (s) => s.subarray(0, Math.max(s.length - 1, 0));
  starts(A.junction_start).forEach((s, k) => addLine(junctions, A.junction_xy, s, A.junction_start[k + 1], true));
  starts(A.marking_start).forEach((s, k) => addLine(markings, A.marking_xy, s, A.marking_start[k + 1], false));
  return { groups: [...groups.values()], junctions, markings };
}
const network = buildNetwork();
timings.network = performance.now();

function drawNetwork(c, scale) {
  c.fillStyle = COLOUR.junction;
  c.fill(network.junctions);
  c.lineCap = "butt"; c.lineJoin = "round";
  for (const g of network.groups) {
    if (g.kind === "walkingarea") { c.fillStyle = COLOUR.walkingarea; c.fill(g.path); continue; }
    c.strokeStyle = COLOUR[g.kind]; c.lineWidth = g.width;
    c.stroke(g.path);
    if (g.kind === "crossing" && scale > 4) {  // zebra stripes
      c.strokeStyle = "#ffffff"; c.setLineDash([0.5, 0.5]); c.stroke(g.path); c.setLineDash([]);
    }
  }
  if (scale < 1) return;  // dashes under 3 px: left out
  c.strokeStyle = COLOUR.marking; c.lineWidth = 0.15; c.setLineDash([3, 6]);
  c.stroke(network.markings);
  c.setLineDash([]);
}

// The network is drawn into an image twice the canvas's size around the view, drawn again only when the view
// zooms or moves out of it; every frame copies it.
let netCache = null;
function blitNetwork() {
  const W = scene.width, H = scene.height, s = view.scale * devicePixelRatio;
  const stale = !netCache || netCache.scale !== view.scale || netCache.W !== W || netCache.H !== H ||
    Math.abs(view.cx - netCache.cx) * s > W / 2 || Math.abs(view.cy - netCache.cy) * s > H / 2;
  if (stale) {
    const off = netCache && netCache.W === W && netCache.H === H ? netCache.canvas : document.createElement("canvas");
    off.width = 2 * W; off.height = 2 * H;
    const c = off.getContext("2d", { alpha: false });
    c.fillStyle = COLOUR.ground; c.fillRect(0, 0, off.width, off.height);
    c.setTransform(s, 0, 0, -s, W - view.cx * s, H + view.cy * s);
    drawNetwork(c, view.scale);
    netCache = { canvas: off, scale: view.scale, cx: view.cx, cy: view.cy, W, H };
  }
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.drawImage(netCache.canvas, Math.round(-W / 2 + (netCache.cx - view.cx) * s),
    Math.round(-H / 2 + (view.cy - netCache.cy) * s));
}

function drawSignals(t) {
  const bars = A.bar_signal.length;
  if (!bars) return;
  const byColour = new Map();
  const states = signalChanges.map((c) => { const i = lastAtOrBefore(c.time, t); return i >= 0 ? c.state[i] : ""; });
  for (let b = 0; b < bars; b++) {
    const colour = SIGNAL[states[A.bar_signal[b]][A.bar_link[b]]];
    if (!colour) continue;
    if (!byColour.has(colour)) byColour.set(colour, new Path2D());
    const p = byColour.get(colour);
    p.moveTo(A.bar_xy[4 * b], A.bar_xy[4 * b + 1]); p.lineTo(A.bar_xy[4 * b + 2], A.bar_xy[4 * b + 3]);
  }
  ctx.lineWidth = 0.8;
  for (const [colour, p] of byColour) { ctx.strokeStyle = colour; ctx.stroke(p); }
}

// ---- vehicles and RSS -------------------------------------------------------------------------------------------
function addBox(p, f, i, grow = 0) {
  const v = f.veh[i], len = A.length[v] + 2 * grow, w = A.width[v] / 2 + grow;
  const c = Math.cos(f.h[i]), s = Math.sin(f.h[i]);
  const fx = f.x[i] + grow * c, fy = f.y[i] + grow * s, bx = fx - len * c, by = fy - len * s;
  p.moveTo(fx - w * s, fy + w * c); p.lineTo(fx + w * s, fy - w * c);
  p.lineTo(bx + w * s, by - w * c); p.lineTo(bx - w * s, by + w * c); p.closePath();
}

function openEpisodes(t) {  // episodes whose danger covers t (episodes.csv is sorted by t_b)
  const open = [];
  const last = lastAtOrBefore(ep.t_b_s, t);
  for (let e = 0; e <= last; e++) if (ep.t_end_s[e] >= t - 1e-9) open.push(e);
  return open;
}

// The world rectangle in view [m], grown by the longest vehicle and 10 px: a vehicle whose front bumper is outside it,
// or a danger line with both ends beyond one of its sides, is not drawn (following a car, most of them are).
const LONGEST = A.length.reduce((m, l) => Math.max(m, l), 0);
function viewBox() {
  const [w, h] = cssSize(), m = LONGEST + 10 / view.scale, hw = w / 2 / view.scale + m, hh = h / 2 / view.scale + m;
  return [view.cx - hw, view.cy - hh, view.cx + hw, view.cy + hh];
}
const inBox = (box, x, y) => x >= box[0] && x <= box[2] && y >= box[1] && y <= box[3];

function drawVehicles(f, open, box) {
  const cars = new Path2D(), egos = new Path2D(), fronts = new Path2D(), danger = new Path2D();
  for (let i = 0; i < f.n; i++) {
    if (!inBox(box, f.x[i], f.y[i])) continue;
    const v = f.veh[i], len = A.length[v], c = Math.cos(f.h[i]), s = Math.sin(f.h[i]), w = A.width[v] / 2;
    addBox(veh.vclass[v] === egoClass ? egos : cars, f, i);
    const wx = f.x[i] - 0.25 * len * c, wy = f.y[i] - 0.25 * len * s;  // windscreen: which way it faces
    fronts.moveTo(wx - w * s, wy + w * c); fronts.lineTo(wx + w * s, wy - w * c);
  }
  for (const e of open) {
    for (const v of [ep.a[e], ep.b[e]]) {
      const i = v >= 0 ? slotOf[v] : -1;
      if (i >= 0 && inBox(box, f.x[i], f.y[i])) addBox(danger, f, i, 0.25);
    }
  }
  const px = 1 / view.scale;
  ctx.lineWidth = 1.5 * px; ctx.strokeStyle = COLOUR.amber; ctx.stroke(danger);
  ctx.fillStyle = COLOUR.car; ctx.fill(cars);
  ctx.fillStyle = COLOUR.ego; ctx.fill(egos);
  ctx.lineWidth = px; ctx.strokeStyle = COLOUR.outline; ctx.stroke(cars); ctx.stroke(egos);
  ctx.lineWidth = Math.max(0.3, 1.5 * px); ctx.stroke(fronts);
  const marked = [[state.picked, COLOUR.selected], [state.follow, COLOUR.selected]];
  for (const [v, colour] of marked) {
    if (v < 0 || slotOf[v] < 0) continue;
    const p = new Path2D(); addBox(p, f, slotOf[v], 0.6);
    ctx.lineWidth = 2 * px; ctx.strokeStyle = colour; ctx.stroke(p);
  }
}

// Each pair of an open episode: a line between the cars' centres, each half coloured by its car (red: it has
// broken its owed response in this episode by now; thicker: it is breaking it now), the selected pair underlaid.
function drawDangerLines(f, open, t, box) {
  const px = 1 / view.scale, halves = [new Path2D(), new Path2D(), new Path2D(), new Path2D()];
  const selected = new Path2D();
  for (const e of open) {
    const a = slotOf[ep.a[e]], b = slotOf[ep.b[e]];
    if (ep.a[e] < 0 || ep.b[e] < 0 || a < 0 || b < 0) continue;
    const ca = centre(f, a), cb = centre(f, b), mid = [(ca[0] + cb[0]) / 2, (ca[1] + cb[1]) / 2];
    if (Math.max(ca[0], cb[0]) < box[0] || Math.min(ca[0], cb[0]) > box[2] || Math.max(ca[1], cb[1]) < box[1] ||
      Math.min(ca[1], cb[1]) > box[3]) continue;
    if (e === state.episode) { selected.moveTo(...ca); selected.lineTo(...cb); }
    [[ca, 0], [cb, 1]].forEach(([end, side]) => {
      const now = violating[e].some(([s, t0, t1]) => s === side && t0 <= t + 1e-9 && t <= t1 + 1e-9);
      const path = halves[(t + 1e-9 >= blameFrom[e][side] ? 2 : 0) + (now ? 1 : 0)];
      path.moveTo(...end); path.lineTo(...mid);
    });
  }
  ctx.lineWidth = 7 * px; ctx.strokeStyle = COLOUR.selected; ctx.stroke(selected);
  halves.forEach((path, k) => {
    ctx.lineWidth = (k % 2 ? 4 : 2.5) * px; ctx.strokeStyle = k >= 2 ? COLOUR.red : COLOUR.amber;
    ctx.stroke(path);
  });
}

const collisionAt = header.collisions.time.map((tc, c) => {  // where each collision happened (collider, else victim)
  const k = stepAt(tc), s = A.step_start[k], e = A.step_start[k + 1];
  for (const v of [header.collisions.collider[c], header.collisions.victim[c]]) {
    for (let r = s; r < e; r++) if (A.vehicle[r] === v) return [A.x[r] * 0.01, A.y[r] * 0.01];
  }
  return null;
});

function drawCollisions(t) {
  const px = 1 / view.scale, r = Math.max(3, 8 * px);
  header.collisions.time.forEach((tc, c) => {
    const at = collisionAt[c];
    if (!at || t < tc - 1e-9 || t > tc + COLLISION_SHOWN_S) return;
    ctx.lineWidth = 3 * px; ctx.strokeStyle = COLOUR.crash;
    ctx.beginPath(); ctx.arc(at[0], at[1], r, 0, 2 * Math.PI); ctx.stroke();
    ctx.strokeStyle = COLOUR.red; ctx.beginPath();
    ctx.moveTo(at[0] - r * 0.7, at[1] - r * 0.7); ctx.lineTo(at[0] + r * 0.7, at[1] + r * 0.7);
    ctx.moveTo(at[0] - r * 0.7, at[1] + r * 0.7); ctx.lineTo(at[0] + r * 0.7, at[1] - r * 0.7); ctx.stroke();
  });
}

function drawLabels(f) {
  ctx.setTransform(devicePixelRatio, 0, 0, devicePixelRatio, 0, 0);
  ctx.font = "bold 12px system-ui, sans-serif"; ctx.textAlign = "center";
  for (let i = 0; i < f.n; i++) {
    if (veh.vclass[f.veh[i]] !== egoClass) continue;
    const [x, y] = toScreen(...centre(f, i));
    ctx.fillStyle = "#ffffff"; ctx.fillRect(x - 13, y - 26, 26, 14);
    ctx.fillStyle = COLOUR.ego; ctx.fillText("ego", x, y - 15);
  }
}

// ---- scene ------------------------------------------------------------------------------------------------------
const cssSize = () => [scene.clientWidth, scene.clientHeight];
function toScreen(x, y) {  // world (relative to origin) → CSS px
  const [w, h] = cssSize();
  return [(x - view.cx) * view.scale + w / 2, h / 2 - (y - view.cy) * view.scale];
}
function toWorld(sx, sy) {
  const [w, h] = cssSize();
  return [(sx - w / 2) / view.scale + view.cx, (h / 2 - sy) / view.scale + view.cy];
}

function render() {
  const started = performance.now();
  const [w, h] = cssSize(), dpr = devicePixelRatio;
  if (scene.width !== Math.round(w * dpr) || scene.height !== Math.round(h * dpr)) {
    scene.width = Math.round(w * dpr); scene.height = Math.round(h * dpr);
  }
  frame = vehiclesAt(state.time);
  state.step = frame.k;
  if (state.follow >= 0 && slotOf[state.follow] >= 0) [view.cx, view.cy] = centre(frame, slotOf[state.follow]);
  blitNetwork();
  const s = view.scale * dpr;
  ctx.setTransform(s, 0, 0, -s, scene.width / 2 - view.cx * s, scene.height / 2 + view.cy * s);
  drawSignals(state.time);
  const open = openEpisodes(state.time);
  const box = viewBox();
  drawDangerLines(frame, open, state.time, box);
  drawVehicles(frame, open, box);
  drawCollisions(state.time);
  drawLabels(frame);
  if (state.step !== state.shownStep) { state.shownStep = state.step; showStep(); }
  stats.frames += 1;
  stats.renderMs.push(performance.now() - started);
  if (stats.renderMs.length > 1000) stats.renderMs.shift();
}

function tick(now) {
  if (state.playing) {
    if (state.wall !== null) state.time += (now - state.wall) / 1000 * state.speed;
    state.wall = now;
    if (state.time >= time[steps - 1]) { state.time = time[steps - 1]; setPlaying(false); }
    state.dirty = true;
  }
  if (state.dirty) { state.dirty = false; render(); }
  requestAnimationFrame(tick);
}

function setPlaying(on) {
  if (on && state.time >= time[steps - 1]) state.time = time[0];
  state.playing = on; state.wall = null;
  $("play").innerHTML = on ? "&#10074;&#10074;" : "&#9654;";
}

function seek(step) {
  state.step = Math.min(Math.max(step, 0), steps - 1);  // now: keys pressed before the next frame add up
  state.time = time[state.step];
  state.wall = null; state.dirty = true;
}

function fit() {
  const [x0, y0, x1, y1] = header.bounds, [w, h] = cssSize();
  view.cx = (x0 + x1) / 2 - header.origin[0]; view.cy = (y0 + y1) / 2 - header.origin[1];
  view.scale = 0.95 * Math.min(w / Math.max(x1 - x0, 1), h / Math.max(y1 - y0, 1));
  state.follow = -1; $("follow").value = ""; state.dirty = true;
}

// ---- per step: clock, slider, timeline, charts, readout ---------------------------------------------------------
function showStep() {
  $("clock").textContent = `${time[state.step].toFixed(1)} s`;
  $("slider").value = String(state.step);
  drawTimeline();
  drawCharts();
  showReadout();
}

let timelineCache = null;
function drawTimeline() {
  const canvas = $("timeline"), w = canvas.clientWidth, h = canvas.clientHeight, dpr = devicePixelRatio;
  const t0 = time[0], span = Math.max(time[steps - 1] - t0, 1e-9), x = (t) => (t - t0) / span * w;
  const key = `${w}|${h}|${state.episode}`;
  if (!timelineCache || timelineCache.key !== key) {
    const off = document.createElement("canvas");
    off.width = Math.round(w * dpr); off.height = Math.round(h * dpr);
    const c = off.getContext("2d");
    c.scale(dpr, dpr);
    if (state.episode >= 0) {
      c.fillStyle = "rgba(124, 58, 237, 0.35)";
      c.fillRect(x(ep.t_b_s[state.episode]), 0, Math.max(2, x(ep.t_end_s[state.episode]) - x(ep.t_b_s[state.episode])), h);
    }
    header.violations.t_start_s.forEach((ts, i) => {  // overlapping ones add up: the darker, the more at once
      c.fillStyle = header.violations.episode[i] === state.episode ? COLOUR.red : "rgba(220, 38, 38, 0.2)";
      c.fillRect(x(ts), 2, Math.max(1, x(header.violations.t_end_s[i]) - x(ts)), h / 2 - 2);
    });
    c.fillStyle = COLOUR.crash;
    header.collisions.time.forEach((tc) => {
      c.beginPath(); c.moveTo(x(tc), h / 2); c.lineTo(x(tc) - 5, h); c.lineTo(x(tc) + 5, h); c.fill();
    });
    timelineCache = { key, canvas: off };
  }
  if (canvas.width !== Math.round(w * dpr) || canvas.height !== Math.round(h * dpr)) {
    canvas.width = Math.round(w * dpr); canvas.height = Math.round(h * dpr);
  }
  const c = canvas.getContext("2d");
  c.setTransform(1, 0, 0, 1, 0, 0);
  c.drawImage(timelineCache.canvas, 0, 0);
  c.scale(dpr, dpr);
  c.fillStyle = "#000"; c.fillRect(x(time[state.step]) - 1, 0, 2, h);
}

function episodeStates(e) {  // the rows of episode e's states: [first, end) (none until they are read)
  return e < 0 || !nStates ? [0, 0] : [ep.state_start[e], ep.state_start[e] + ep.state_count[e]];
}

function chartData() {  // what the charts of the selected episode plot (for tests and scripts)
  const [s, e] = episodeStates(state.episode);
  const column = (name, side) => e === s ? [] : side === undefined ? Array.from(A[`state_${name}`].subarray(s, e))
    : Array.from({ length: e - s }, (_, i) => A[`state_${name}`][side * nStates + s + i]);
  return { time: column("time"), lon_gap: column("lon_gap"), lon_d_min: column("lon_d_min"),
    lat_gap: column("lat_gap"), lat_d_min: column("lat_d_min"),
    accel_a: column("accel", 0), accel_b: column("accel", 1), accel_max_a: column("accel_max", 0),
    accel_max_b: column("accel_max", 1), accel_min_a: column("accel_min", 0), accel_min_b: column("accel_min", 1),
    lat_speed_a: column("lat_speed", 0), lat_speed_b: column("lat_speed", 1),
    lat_speed_max_a: column("lat_speed_max", 0), lat_speed_max_b: column("lat_speed_max", 1) };
}

// A chart of time series (NaN breaks a line) on `canvas`, drawn once into an image kept for the episode; each step
// copies it and draws the time cursor.
function chart(canvas, title, series, t0, t1, spans, empty) {
  const w = canvas.clientWidth, h = canvas.clientHeight, dpr = devicePixelRatio;
  const off = document.createElement("canvas");
  off.width = Math.round(w * dpr); off.height = Math.round(h * dpr);
  const c = off.getContext("2d");
  c.scale(dpr, dpr);
  const left = 44, right = 6, top = 14, bottom = 16;
  const X = (t) => left + (t - t0) / Math.max(t1 - t0, 1e-9) * (w - left - right);
  canvas.cache = { image: off, X, top, bottom };
  c.fillStyle = "#fff"; c.fillRect(0, 0, w, h);
  let lo = Infinity, hi = -Infinity;
  for (const s of series) for (const v of s.v) if (Number.isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
  c.fillStyle = "#333"; c.font = "11px system-ui, sans-serif"; c.textAlign = "left";
  c.fillText(title, left, 10);
  if (!Number.isFinite(lo)) { c.fillStyle = "#888"; c.fillText(empty, left, h / 2); return; }
  lo = Math.min(lo, 0); hi = Math.max(hi, 0);
  const pad = (hi - lo) * 0.08 || 1; lo -= pad; hi += pad;
  const Y = (v) => top + (hi - v) / (hi - lo) * (h - top - bottom);
  c.fillStyle = "rgba(220, 38, 38, 0.15)";
  for (const [a, b] of spans) c.fillRect(X(a), top, Math.max(2, X(b) - X(a)), h - top - bottom);
  c.strokeStyle = "#ccc"; c.lineWidth = 1;
  c.beginPath(); c.moveTo(left, Y(0)); c.lineTo(w - right, Y(0)); c.stroke();
  c.fillStyle = "#666"; c.textAlign = "right";
  c.fillText(hi.toFixed(1), left - 3, top + 8); c.fillText(lo.toFixed(1), left - 3, h - bottom);
  c.textAlign = "left"; c.fillText(`${t0.toFixed(1)} s`, left, h - 3);
  c.textAlign = "right"; c.fillText(`${t1.toFixed(1)} s`, w - right, h - 3);
  c.font = "11px system-ui, sans-serif";
  let legend = w - right - series.reduce((sum, s) => sum + c.measureText(s.label).width + 10, 0);
  for (const s of series) {
    c.strokeStyle = s.colour; c.lineWidth = 1.5; c.setLineDash(s.dash || []);
    c.beginPath();
    let pen = false;
    s.t.forEach((t, i) => {
      const v = s.v[i];
      if (!Number.isFinite(v)) { pen = false; return; }
      if (pen) c.lineTo(X(t), Y(v)); else c.moveTo(X(t), Y(v));
      pen = true;
    });
    c.stroke(); c.setLineDash([]);
    c.fillStyle = s.colour; c.textAlign = "left"; c.fillText(s.label, legend, 10); legend += c.measureText(s.label).width + 10;
  }
}

function showCursor(canvas) {
  const { image, X, top, bottom } = canvas.cache, h = canvas.clientHeight, dpr = devicePixelRatio;
  if (canvas.width !== image.width || canvas.height !== image.height) { canvas.width = image.width; canvas.height = image.height; }
  const c = canvas.getContext("2d");
  c.setTransform(1, 0, 0, 1, 0, 0);
  c.drawImage(image, 0, 0);
  c.setTransform(dpr, 0, 0, dpr, 0, 0);
  c.strokeStyle = "#000"; c.lineWidth = 1;
  c.beginPath(); c.moveTo(X(time[state.step]), top); c.lineTo(X(time[state.step]), h - bottom); c.stroke();
}

const charts = ["chart-lon", "chart-lat", "chart-accel", "chart-latspeed"].map($);
let chartsKey = null;
function drawCharts() {
  const key = `${state.episode}|${charts[0].clientWidth}|${charts[0].clientHeight}`;
  if (key !== chartsKey) { chartsKey = key; drawChartImages(); }
  charts.forEach(showCursor);
}

function drawChartImages() {
  const e = state.episode, d = chartData();
  const t0 = e >= 0 ? ep.t_b_s[e] : 0, t1 = e >= 0 ? Math.max(ep.t_end_s[e], t0 + 0.1) : 1;
  const pad = Math.max(0.5, 0.1 * (t1 - t0));
  const spans = e >= 0 ? violating[e].map(([, a, b]) => [a, b]) : [];
  const [ca, cb] = ["#2563eb", "#ea580c"];
  const s = (v, colour, label, dash) => ({ t: d.time, v, colour, label, dash });
  const cut = header.states_cut_at;
  const empty = e < 0 ? "" : !nStates ? "reading the states ..." : ep.state_count[e] > 0 ? "none here" :
    cut !== null && ep.t_end_s[e] >= cut ? `not recorded (from ${cut} s on, only the ego's episodes were)` : "not recorded";
  chart($("chart-lon"), "longitudinal [m]", [s(d.lon_gap, "#111", "gap"), s(d.lon_d_min, COLOUR.red, "d_min", [5, 3])],
    t0 - pad, t1 + pad, [], empty);
  chart($("chart-lat"), "lateral [m]", [s(d.lat_gap, "#111", "gap"), s(d.lat_d_min, COLOUR.red, "d_min", [5, 3])],
    t0 - pad, t1 + pad, [], empty);
  chart($("chart-accel"), "acceleration [m/s²], owed bounds dashed", [s(d.accel_a, ca, "a"), s(d.accel_max_a, ca, "a ≤", [5, 3]),
    s(d.accel_min_a, ca, "a ≥", [2, 2]), s(d.accel_b, cb, "b"), s(d.accel_max_b, cb, "b ≤", [5, 3]),
    s(d.accel_min_b, cb, "b ≥", [2, 2])], t0 - pad, t1 + pad, spans, empty);
  chart($("chart-latspeed"), "lateral speed towards the other [m/s]", [s(d.lat_speed_a, ca, "a"),
    s(d.lat_speed_max_a, ca, "a ≤", [5, 3]), s(d.lat_speed_b, cb, "b"), s(d.lat_speed_max_b, cb, "b ≤", [5, 3])],
  t0 - pad, t1 + pad, spans, empty);
}

function stateRow(e, t) {  // the row of episode e's states at time t (-1: none)
  const [s, end] = episodeStates(e);
  const i = lastAtOrBefore(A.state_time.subarray(s, end), t + 5e-4);  // state times: float32 of whole ms
  return i >= 0 && Math.abs(A.state_time[s + i] - t) < 5e-4 ? s + i : -1;
}

function showReadout() {  // the selected episode's values at the current step (td[data-field] for scripts)
  const e = state.episode, r = e < 0 ? -1 : stateRow(e, time[state.step]);
  if (r < 0) {
    setReadout(e < 0 ? "" : `<tr><td>at ${time[state.step].toFixed(1)} s the pair is not in this episode</td></tr>`);
    return;
  }
  const fmt = (v) => (Number.isFinite(v) ? v.toFixed(2) : "–");
  const cells = (...fields) => fields.map(([name, v]) => `<td data-field="${name}">${fmt(v)}</td>`).join("");
  const row = (label, ...fields) => `<tr><td>${label}</td>${cells(...fields)}</tr>`;
  const car = (name, side) => A[`state_${name}`][side * nStates + r];
  const rows = [
    row("t [s]", ["time", A.state_time[r]]),
    row("lon gap / d_min [m]", ["lon_gap", A.state_lon_gap[r]], ["lon_d_min", A.state_lon_d_min[r]]),
    row("lat gap / d_min [m]", ["lat_gap", A.state_lat_gap[r]], ["lat_d_min", A.state_lat_d_min[r]]),
  ];
  for (const [side, n, id] of [[0, "a", ep.vehicle_a[e]], [1, "b", ep.vehicle_b[e]]]) {
    rows.push(row(`${n} ${escape(id)}: accel, ≤, ≥ [m/s²]`, [`accel_${n}`, car("accel", side)],
      [`accel_max_${n}`, car("accel_max", side)], [`accel_min_${n}`, car("accel_min", side)]));
    rows.push(row(`${n}: lateral speed, ≤ [m/s]`, [`lat_speed_${n}`, car("lat_speed", side)],
      [`lat_speed_max_${n}`, car("lat_speed_max", side)]));
  }
  setReadout(rows.join(""));
}

let readoutHtml = "";
function setReadout(html) {  // the same rows again (no episode selected) cost no layout
  if (html !== readoutHtml) { readoutHtml = html; $("readout").innerHTML = html; }
}

// ---- selection and episode list ---------------------------------------------------------------------------------
function escape(text) { return String(text).replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`); }

function describe(e) {  // the selected episode's header: the pair, what happened, who owed what, the violations
  const v = header.violations, span = (a, b) => `${a.toFixed(1)}–${b.toFixed(1)} s`;
  const area = ep.conflict_area[e] ? ` ${escape(ep.conflict_area[e])}` : "";
  const broken = v.episode.flatMap((x, i) => (x === e ? [i] : [])).map((i) =>
    `<div class="note">${escape(v.vehicle_id[i])} broke ${escape(v.constraint[i])}: ${v.worst_actual[i].toFixed(2)}` +
    ` vs bound ${v.bound[i].toFixed(2)}, ${span(v.t_start_s[i], v.t_end_s[i])}</div>`);
  return [
    `<h2>${escape(ep.vehicle_a[e])} (a, ${escape(ep.class_a[e])}) – ${escape(ep.vehicle_b[e])} (b, ${escape(ep.class_b[e])})</h2>`,
    `<div>${escape(ep.situation[e])}${area}, trigger ${escape(ep.trigger[e])}, ${span(ep.t_b_s[e], ep.t_end_s[e])}` +
    ` (ended by ${escape(ep.ended_by[e])})</div>`,
    `<div>owed: a <b>${escape(ep.owed_a[e] || "nothing")}</b>, b <b>${escape(ep.owed_b[e] || "nothing")}</b>; ` +
    `responsible: <b class="resp-${escape(ep.responsible[e])}">${escape(ep.responsible[e])}</b></div>`,
    ...broken,
  ].join("");
}

function selectEpisode(e, jump) {  // jump: to its t_b, centred on the pair
  state.episode = e;
  $("selection").innerHTML = e < 0 ? "" : describe(e);
  for (const row of document.querySelectorAll("#episodes tr.selected")) row.classList.remove("selected");
  document.querySelector(`#episodes tr[data-episode="${e}"]`)?.classList.add("selected");
  if (jump && e >= 0) {
    const k = stepAt(ep.t_b_s[e]);
    seek(time[k] < ep.t_b_s[e] - 1e-6 ? k + 1 : k);  // the first recorded step from t_b on
    setPlaying(false);
    frame = vehiclesAt(state.time);
    const a = ep.a[e] >= 0 ? slotOf[ep.a[e]] : -1, b = ep.b[e] >= 0 ? slotOf[ep.b[e]] : -1;
    if (a >= 0 && b >= 0) {
      const ca = centre(frame, a), cb = centre(frame, b);
      [view.cx, view.cy] = [(ca[0] + cb[0]) / 2, (ca[1] + cb[1]) / 2];
      state.follow = -1; $("follow").value = "";
    }
  }
  timelineCache = null; state.shownStep = -1; state.dirty = true;
}

const list = { key: "t_b_s", ascending: true, filter: "" };
function sortValue(e, key) {
  if (key === "pair") return `${ep.vehicle_a[e]} ${ep.vehicle_b[e]}`;
  const v = ep[key][e];
  return v === null ? Infinity : v;
}
function showList() {
  const f = list.filter.toLowerCase(), sign = list.ascending ? 1 : -1;
  const matches = (e) => `${ep.vehicle_a[e]} ${ep.vehicle_b[e]} ${ep.situation[e]} ${ep.responsible[e]}`.toLowerCase().includes(f);
  const rows = Array.from({ length: nEpisodes }, (_, e) => e).filter((e) => !f || matches(e));
  rows.sort((p, q) => {
    const a = sortValue(p, list.key), b = sortValue(q, list.key);
    return (a < b ? -1 : a > b ? 1 : p - q) * sign;
  });
  const num = (v, digits) => `<td class="num">${v === null ? "" : v.toFixed(digits)}</td>`;
  const text = (v, css = "") => `<td${css ? ` class="${css}"` : ""}>${escape(v)}</td>`;
  $("episodes").tBodies[0].innerHTML = rows.slice(0, MAX_LIST_ROWS).map((e) =>
    `<tr data-episode="${e}"${e === state.episode ? ' class="selected"' : ""}>${num(ep.t_b_s[e], 1)}` +
    `${text(`${ep.vehicle_a[e]} – ${ep.vehicle_b[e]}`)}${text(ep.situation[e])}${num(ep.duration_s[e], 1)}` +
    `${num(ep.min_lon_margin_m[e], 2)}${num(ep.min_lat_margin_m[e], 2)}` +
    `${text(ep.responsible[e], `resp-${escape(ep.responsible[e])}`)}</tr>`).join("");
  $("episode-count").textContent = rows.length > MAX_LIST_ROWS ? `(${MAX_LIST_ROWS} of ${rows.length} shown)` : `(${rows.length})`;
  for (const th of document.querySelectorAll("#episodes th")) {
    th.classList.toggle("asc", th.dataset.key === list.key && list.ascending);
    th.classList.toggle("desc", th.dataset.key === list.key && !list.ascending);
  }
}

// ---- input ------------------------------------------------------------------------------------------------------
function pick(sx, sy) {  // the vehicle under the pointer, else the danger line nearest to it (within 6 px)
  const [wx, wy] = toWorld(sx, sy);
  for (let i = 0; i < frame.n; i++) {
    const v = frame.veh[i], c = Math.cos(frame.h[i]), s = Math.sin(frame.h[i]);
    const dx = wx - frame.x[i], dy = wy - frame.y[i], along = dx * c + dy * s, across = -dx * s + dy * c;
    if (along <= 0.5 && along >= -A.length[v] - 0.5 && Math.abs(across) <= A.width[v] / 2 + 0.5) return { vehicle: v };
  }
  let best = -1, bestPx = 6;
  for (const e of openEpisodes(state.time)) {
    const a = slotOf[ep.a[e]], b = slotOf[ep.b[e]];
    if (ep.a[e] < 0 || ep.b[e] < 0 || a < 0 || b < 0) continue;
    const [ax, ay] = toScreen(...centre(frame, a)), [bx, by] = toScreen(...centre(frame, b));
    const L = Math.hypot(bx - ax, by - ay) || 1;
    const u = Math.max(0, Math.min(1, ((sx - ax) * (bx - ax) + (sy - ay) * (by - ay)) / (L * L)));
    const d = Math.hypot(sx - ax - u * (bx - ax), sy - ay - u * (by - ay));
    if (d < bestPx) { best = e; bestPx = d; }
  }
  return { episode: best };
}

function showPicked() {
  const v = state.picked, i = v >= 0 ? slotOf[v] : -1;
  $("picked").textContent = v < 0 ? "" : `${veh.ids[v]} (${veh.classes[veh.vclass[v]]}, ${veh.vtype[v]})` +
    (i >= 0 ? `  ${frame.speed[i].toFixed(1)} m/s` : "  not recorded now") + "  – double-click: follow";
}

function follow(id) {
  state.follow = veh.ids.indexOf(id);
  $("follow").value = state.follow >= 0 ? id : "";
  state.dirty = true;
}

let drag = null;
scene.addEventListener("pointerdown", (ev) => {
  drag = { x: ev.offsetX, y: ev.offsetY, moved: false };
  scene.setPointerCapture(ev.pointerId);
});
scene.addEventListener("pointermove", (ev) => {
  if (!drag) return;
  const dx = ev.offsetX - drag.x, dy = ev.offsetY - drag.y;
  if (!drag.moved && Math.hypot(dx, dy) < 3) return;
  drag.moved = true; state.follow = -1; $("follow").value = "";
  view.cx -= dx / view.scale; view.cy += dy / view.scale;
  drag.x = ev.offsetX; drag.y = ev.offsetY; state.dirty = true;
});
scene.addEventListener("pointerup", (ev) => {
  if (drag && !drag.moved) {
    const hit = pick(ev.offsetX, ev.offsetY);
    if (hit.vehicle === undefined && hit.episode >= 0) selectEpisode(hit.episode, false);
    else { state.picked = hit.vehicle ?? -1; showPicked(); }
    state.dirty = true;
  }
  drag = null;
});
scene.addEventListener("dblclick", () => { if (state.picked >= 0) follow(veh.ids[state.picked]); });
scene.addEventListener("wheel", (ev) => {
  ev.preventDefault();
  const before = toWorld(ev.offsetX, ev.offsetY);
  view.scale = Math.min(200, Math.max(0.01, view.scale * Math.exp(-ev.deltaY * 0.0015)));
  if (state.follow < 0) {
    const after = toWorld(ev.offsetX, ev.offsetY);
    view.cx += before[0] - after[0]; view.cy += before[1] - after[1];
  }
  state.dirty = true;
}, { passive: false });
$("play").addEventListener("click", () => setPlaying(!state.playing));
$("speed").addEventListener("change", (ev) => { state.speed = Number(ev.target.value); });
$("slider").addEventListener("input", (ev) => seek(Number(ev.target.value)));
$("timeline").addEventListener("click", (ev) => {
  const w = ev.target.clientWidth, t = time[0] + ev.offsetX / w * (time[steps - 1] - time[0]);
  seek(stepAt(t));
});
$("fit").addEventListener("click", fit);
$("follow").addEventListener("change", (ev) => follow(ev.target.value.trim()));
$("filter").addEventListener("input", (ev) => { list.filter = ev.target.value; showList(); });
$("episodes").tHead.addEventListener("click", (ev) => {
  const key = ev.target.closest("th")?.dataset.key;
  if (!key) return;
  list.ascending = list.key === key ? !list.ascending : true;
  list.key = key; showList();
});
$("episodes").tBodies[0].addEventListener("click", (ev) => {
  const row = ev.target.closest("tr");
  if (row) selectEpisode(Number(row.dataset.episode), true);
});
document.addEventListener("keydown", (ev) => {
  if (ev.target.tagName === "INPUT" && ev.target.type !== "range") return;
  if (ev.key === " ") { ev.preventDefault(); setPlaying(!state.playing); }
  if (ev.key === "ArrowRight" || ev.key === "ArrowLeft") {
    ev.preventDefault(); setPlaying(false);
    seek(state.step + (ev.key === "ArrowRight" ? 1 : -1) * (ev.shiftKey ? 10 : 1));
  }
});
new ResizeObserver(() => { timelineCache = null; state.shownStep = -1; state.dirty = true; }).observe(document.body);

// ---- start ------------------------------------------------------------------------------------------------------
$("slider").max = String(Math.max(steps - 1, 0));
$("vehicle-ids").innerHTML = veh.ids.slice(0, 5000).map((id) => `<option value="${escape(id)}">`).join("");
$("scope").textContent = header.scope === "all" ? "every vehicle recorded"
  : `vehicles within ${header.scope.split(":")[1]} m of the ego recorded`;
showList();
timings.list = performance.now();
fit();
const ego = veh.vclass.indexOf(egoClass);
if (egoClass >= 0 && ego >= 0) { view.scale = 6; follow(veh.ids[ego]); }
render();
requestAnimationFrame(tick);

// For tests and scripts: the page's state and a few controls.
window.sumoRssViewer = {
  loadMs: performance.now(), timings, stats, header, steps, time: (k) => time[k],
  state: () => ({ step: state.step, time: state.time, playing: state.playing, episode: state.episode, follow: state.follow,
    view: { ...view } }),
  seek: (k) => { seek(k); render(); }, stepAt, selectEpisode: (e) => { selectEpisode(e, true); render(); },
  setView: (cx, cy, scale) => {  // world point at the centre [m], px per m
    state.follow = -1; [view.cx, view.cy, view.scale] = [cx - header.origin[0], cy - header.origin[1], scale]; render();
  },
  toScreen: (x, y) => toScreen(x - header.origin[0], y - header.origin[1]), follow: (id) => { follow(id); render(); },
  play: (speed = 1) => { state.speed = speed; setPlaying(true); }, pause: () => setPlaying(false), chartData,
};
document.body.dataset.ready = "true";

// The episodes' states (the charts' data, most of the page's bytes), read once the replay is on screen.
Object.assign(A, arrays(await inflate("state-blob"), header.state_blob));
nStates = A.state_time.length;
timings.states = performance.now();
chartsKey = null; state.shownStep = -1; state.dirty = true;
document.body.dataset.states = "ready";
