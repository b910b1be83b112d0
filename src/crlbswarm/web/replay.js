// crlbswarm replay page: draws a batch of missions from the data inlined in the page.
// Vanilla JavaScript and canvas; nothing is loaded from anywhere. docs/replay.md describes
// the data, the controls and window.crlbReplay, the page's state for scripts and tests.
(function () {
  "use strict";

  const D = JSON.parse(document.getElementById("crlb-replay-data").textContent);

  // -- data ---------------------------------------------------------------------------
  function f32(text) {
    if (text === null || text === undefined) return null;
    const bin = atob(text);
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Float32Array(bytes.buffer);
  }

  const T = D.frameTime; // time of each frame (the map), s
  const F = T.length; // frames per run
  const TS = D.seriesTime; // time of each point of the time series (their own sampling), s
  const S = TS.length; // points per run and series
  const NR = D.runIndex.length; // runs in the page
  const SERIES = ["crlb", "cost", "eta", "clearance", "separation"];
  const groups = D.groups.map(function (g) {
    const series = {};
    const envelope = {};
    for (const name of SERIES) {
      series[name] = f32(g.series[name]);
      envelope[name] = g.envelope ? f32(g.envelope[name]) : null;
    }
    return {
      uavs: g.uavs, M: g.uavs.length, leader: g.leader, bound: g.bound,
      boundLabel: g.boundLabel, formationLabel: g.formationLabel,
      slotOffsets: g.slotOffsets, moving: g.targetMoving, target: f32(g.target),
      estimate: f32(g.estimate), pos: f32(g.positions), series: series, envelope: envelope,
      metrics: g.metrics,
    };
  });
  let NU = 0;
  for (const g of groups) NU += g.M;

  // -- colours --------------------------------------------------------------------------
  const PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2",
    "#bcbd22", "#17becf"];
  const LEADER = "#d62728";
  const GROUP_COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#9467bd", "#8c564b", "#e377c2"];
  function hex(v) { return Math.round(v * 255).toString(16).padStart(2, "0"); }
  function hslHex(h, s, l) { // h in [0, 1)
    const a = s * Math.min(l, 1 - l);
    const f = function (n) {
      const k = (n + h * 12) % 12;
      return l - a * Math.max(-1, Math.min(k - 3, 9 - k, 1));
    };
    return "#" + hex(f(0)) + hex(f(8)) + hex(f(4));
  }
  const UAV_COLOURS = new Array(NU);
  const LEADERS = new Set(groups.map(function (g) { return g.leader; }));
  (function () {
    let k = 0;
    for (let u = 0; u < NU; u++) {
      if (LEADERS.has(u)) { UAV_COLOURS[u] = LEADER; continue; }
      UAV_COLOURS[u] = k < PALETTE.length ? PALETTE[k]
        : hslHex(((k - PALETTE.length) * 0.618034 + 0.13) % 1, 0.62, 0.42);
      k++;
    }
  })();
  function groupColour(gi) { return GROUP_COLOURS[gi % GROUP_COLOURS.length]; }

  // -- state ----------------------------------------------------------------------------
  const state = { run: 0, time: T[0], playing: false, speed: 10, last: null };

  function sampleAt(times, t) { // the sample at or before t and the weight of the next one
    const n = times.length;
    if (n === 1 || t <= times[0]) return { i: 0, w: 0 };
    if (t >= times[n - 1]) return { i: n - 1, w: 0 };
    let lo = 0;
    let hi = n - 1;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (times[mid] <= t) lo = mid; else hi = mid;
    }
    return { i: lo, w: (t - times[lo]) / (times[lo + 1] - times[lo]) };
  }
  function frameAt(t) { return sampleAt(T, t); } // the map's frames
  function pointAt(t) { return sampleAt(TS, t); } // the time series' points
  function lerp2(arr, base, stride, fr) { // [x, y] at frame fr of a (frames, ..., 2) block
    const a = base + fr.i * stride;
    if (fr.w === 0) return [arr[a], arr[a + 1]];
    const b = a + stride;
    return [arr[a] + (arr[b] - arr[a]) * fr.w, arr[a + 1] + (arr[b + 1] - arr[a + 1]) * fr.w];
  }
  function uavAt(g, r, m, fr) { return lerp2(g.pos, ((r * F) * g.M + m) * 2, g.M * 2, fr); }
  function targetAt(g, r, fr) {
    if (!g.moving) return [g.target[r * 2], g.target[r * 2 + 1]];
    return lerp2(g.target, r * F * 2, 2, fr);
  }
  function estimateAt(g, r, fr) { return g.estimate ? lerp2(g.estimate, r * F * 2, 2, fr) : null; }
  function seriesAt(g, name, r, t) { // a series at time t (between points: linear)
    const s = g.series[name];
    const pt = pointAt(t);
    const a = s[r * S + pt.i];
    if (pt.w === 0) return a;
    const b = s[r * S + pt.i + 1];
    return isFinite(a) && isFinite(b) ? a + (b - a) * pt.w : a;
  }

  // -- map ------------------------------------------------------------------------------
  const wrap = document.getElementById("map-wrap");
  const map = document.getElementById("map");
  const mctx = map.getContext("2d");
  const view = { cx: 0, cy: 0, scale: 1, user: false, W: 300, H: 300 };

  function w2c(x, y) { return [view.W / 2 + (x - view.cx) * view.scale, view.H / 2 - (y - view.cy) * view.scale]; }
  function c2w(px, py) { return [view.cx + (px - view.W / 2) / view.scale, view.cy - (py - view.H / 2) / view.scale]; }

  function runBounds(r) {
    const b = [Infinity, -Infinity, Infinity, -Infinity];
    const add = function (x, y) {
      if (!isFinite(x) || !isFinite(y)) return;
      b[0] = Math.min(b[0], x); b[1] = Math.max(b[1], x);
      b[2] = Math.min(b[2], y); b[3] = Math.max(b[3], y);
    };
    for (const g of groups) {
      const base = r * F * g.M * 2;
      for (let k = 0; k < F * g.M; k++) add(g.pos[base + 2 * k], g.pos[base + 2 * k + 1]);
      for (let i = 0; i < (g.moving ? F : 1); i++) {
        const p = targetAt(g, r, { i: i, w: 0 });
        add(p[0], p[1]);
        for (const o of g.slotOffsets) add(p[0] + o[0], p[1] + o[1]);
      }
    }
    if (!isFinite(b[0])) return [-1, 1, -1, 1];
    return b;
  }
  function fitView() {
    const b = runBounds(state.run);
    const w = Math.max(b[1] - b[0], 10);
    const h = Math.max(b[3] - b[2], 10);
    view.scale = Math.min(view.W / (w * 1.12), view.H / (h * 1.12));
    view.cx = (b[0] + b[1]) / 2;
    view.cy = (b[2] + b[3]) / 2;
    view.user = false;
  }
  function resizeMap() {
    const r = wrap.getBoundingClientRect();
    const dpr = window.devicePixelRatio || 1;
    view.W = Math.max(100, Math.floor(r.width));
    view.H = Math.max(100, Math.floor(r.height));
    map.width = Math.round(view.W * dpr);
    map.height = Math.round(view.H * dpr);
    map.style.width = view.W + "px";
    map.style.height = view.H + "px";
    mctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    if (!view.user) fitView();
  }

  function niceStep(raw) {
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    const f = raw / p;
    return (f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10) * p;
  }
  function fmt(v) {
    if (v === null || v === undefined || !isFinite(v)) return "–";
    const a = Math.abs(v);
    if (a !== 0 && (a >= 1e5 || a < 1e-3)) return v.toExponential(2);
    return String(Number(v.toPrecision(4)));
  }

  function drawGrid(ctx) {
    const step = niceStep(90 / view.scale);
    const a = c2w(0, view.H);
    const b = c2w(view.W, 0);
    ctx.lineWidth = 1;
    ctx.strokeStyle = "#ececec";
    ctx.fillStyle = "#999";
    ctx.font = "10px sans-serif";
    ctx.beginPath();
    for (let x = Math.ceil(a[0] / step) * step; x <= b[0]; x += step) {
      const px = Math.round(w2c(x, 0)[0]) + 0.5;
      ctx.moveTo(px, 0); ctx.lineTo(px, view.H);
    }
    for (let y = Math.ceil(a[1] / step) * step; y <= b[1]; y += step) {
      const py = Math.round(w2c(0, y)[1]) + 0.5;
      ctx.moveTo(0, py); ctx.lineTo(view.W, py);
    }
    ctx.stroke();
    ctx.textAlign = "left";
    for (let x = Math.ceil(a[0] / step) * step; x <= b[0]; x += step) {
      ctx.fillText(fmt(x) + " m", w2c(x, 0)[0] + 2, view.H - 4);
    }
    for (let y = Math.ceil(a[1] / step) * step; y <= b[1]; y += step) {
      ctx.fillText(fmt(y) + " m", 3, w2c(0, y)[1] - 2);
    }
  }
  function drawObstacles(ctx) {
    ctx.fillStyle = "rgba(128,128,128,0.78)";
    for (const o of D.obstacles.rectangles) { // [x0, x1, y0, y1]
      const p = w2c(o[0], o[3]);
      const q = w2c(o[1], o[2]);
      ctx.fillRect(p[0], p[1], q[0] - p[0], q[1] - p[1]);
    }
    for (const o of D.obstacles.circles) { // [cx, cy, r]
      const c = w2c(o[0], o[1]);
      ctx.beginPath();
      ctx.arc(c[0], c[1], o[2] * view.scale, 0, 2 * Math.PI);
      ctx.fill();
    }
  }
  function byAngle(points) { // in order of angle around their centroid, the nearer first on
    // a tie: crlbswarm.geometry.outline_order, a polygon that never crosses itself
    let cx = 0;
    let cy = 0;
    for (const p of points) { cx += p[0]; cy += p[1]; }
    cx /= points.length; cy /= points.length;
    return points.slice().sort(function (p, q) {
      const a = Math.atan2(p[1] - cy, p[0] - cx) - Math.atan2(q[1] - cy, q[0] - cx);
      return a !== 0 ? a : Math.hypot(p[0] - cx, p[1] - cy) - Math.hypot(q[0] - cx, q[1] - cy);
    });
  }
  function polygon(ctx, points) {
    ctx.beginPath();
    points.forEach(function (p, k) {
      const c = w2c(p[0], p[1]);
      if (k === 0) ctx.moveTo(c[0], c[1]); else ctx.lineTo(c[0], c[1]);
    });
    ctx.closePath();
  }
  function pathOf(ctx, arr, base, stride, upto, fr) { // a polyline over the frames to fr
    ctx.beginPath();
    let started = false;
    for (let i = 0; i <= upto; i++) {
      const x = arr[base + i * stride];
      const y = arr[base + i * stride + 1];
      if (!isFinite(x) || !isFinite(y)) continue;
      const c = w2c(x, y);
      if (started) ctx.lineTo(c[0], c[1]); else { ctx.moveTo(c[0], c[1]); started = true; }
    }
    if (fr && fr.w > 0) {
      const p = lerp2(arr, base, stride, fr);
      const c = w2c(p[0], p[1]);
      ctx.lineTo(c[0], c[1]);
    }
  }
  function star(ctx, x, y, r) {
    ctx.beginPath();
    for (let k = 0; k < 10; k++) {
      const a = -Math.PI / 2 + k * Math.PI / 5;
      const rr = k % 2 ? r * 0.45 : r;
      const px = x + rr * Math.cos(a);
      const py = y + rr * Math.sin(a);
      if (k === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
    }
    ctx.closePath();
  }

  function drawMap() {
    const ctx = mctx;
    const r = state.run;
    const fr = frameAt(state.time);
    ctx.fillStyle = "#ffffff";
    ctx.fillRect(0, 0, view.W, view.H);
    drawGrid(ctx);
    drawObstacles(ctx);
    ctx.lineJoin = "round";
    groups.forEach(function (g) { // F* over the target, the target's path, the estimate's
      const tg = targetAt(g, r, fr);
      ctx.setLineDash([6, 4]);
      ctx.strokeStyle = "rgba(214,39,40,0.75)";
      ctx.lineWidth = 1.2;
      polygon(ctx, byAngle(g.slotOffsets.map(function (o) { return [tg[0] + o[0], tg[1] + o[1]]; })));
      ctx.stroke();
      if (g.moving) {
        ctx.setLineDash([2, 3]);
        ctx.strokeStyle = "rgba(60,60,60,0.7)";
        pathOf(ctx, g.target, r * F * 2, 2, F - 1, null);
        ctx.stroke();
      }
      if (g.estimate) {
        ctx.setLineDash([4, 3]);
        ctx.strokeStyle = "rgba(200,0,120,0.55)";
        ctx.lineWidth = 1;
        pathOf(ctx, g.estimate, r * F * 2, 2, fr.i, fr);
        ctx.stroke();
      }
      ctx.setLineDash([]);
    });
    groups.forEach(function (g) { // tracks: whole (faint), flown so far (strong)
      for (let m = 0; m < g.M; m++) {
        const u = g.uavs[m];
        const base = ((r * F) * g.M + m) * 2;
        ctx.strokeStyle = UAV_COLOURS[u];
        ctx.globalAlpha = 0.2;
        ctx.lineWidth = 1;
        pathOf(ctx, g.pos, base, g.M * 2, F - 1, null);
        ctx.stroke();
        ctx.globalAlpha = 0.9;
        ctx.lineWidth = u === g.leader ? 2.2 : 1.4;
        pathOf(ctx, g.pos, base, g.M * 2, fr.i, fr);
        ctx.stroke();
      }
      ctx.globalAlpha = 1;
    });
    const now = groups.map(function (g) {
      const pts = [];
      for (let m = 0; m < g.M; m++) pts.push(uavAt(g, r, m, fr));
      return pts;
    });
    groups.forEach(function (g, gi) { // the formation polygon, in order of angle
      polygon(ctx, byAngle(now[gi]));
      ctx.fillStyle = "rgba(31,119,180,0.07)";
      ctx.fill();
      ctx.strokeStyle = "#222";
      ctx.lineWidth = 1.3;
      ctx.stroke();
    });
    groups.forEach(function (g) { // target and estimate
      const tg = targetAt(g, r, fr);
      const c = w2c(tg[0], tg[1]);
      star(ctx, c[0], c[1], 9);
      ctx.fillStyle = "#111";
      ctx.fill();
      const e = estimateAt(g, r, fr);
      if (e && isFinite(e[0]) && isFinite(e[1])) {
        const q = w2c(e[0], e[1]);
        ctx.strokeStyle = "#c80078";
        ctx.lineWidth = 2.2;
        ctx.beginPath();
        ctx.moveTo(q[0] - 6, q[1] - 6); ctx.lineTo(q[0] + 6, q[1] + 6);
        ctx.moveTo(q[0] - 6, q[1] + 6); ctx.lineTo(q[0] + 6, q[1] - 6);
        ctx.stroke();
      }
    });
    groups.forEach(function (g, gi) { // the UAVs, last: on top of everything
      for (let m = 0; m < g.M; m++) {
        const u = g.uavs[m];
        const c = w2c(now[gi][m][0], now[gi][m][1]);
        ctx.beginPath();
        ctx.arc(c[0], c[1], u === g.leader ? 6.5 : 5, 0, 2 * Math.PI);
        ctx.fillStyle = UAV_COLOURS[u];
        ctx.fill();
        ctx.strokeStyle = "#ffffff";
        ctx.lineWidth = 1.2;
        ctx.stroke();
      }
    });
    drawScaleBar(ctx);
  }
  function drawScaleBar(ctx) {
    const len = niceStep(110 / view.scale);
    const px = len * view.scale;
    const x0 = view.W - px - 16;
    const y0 = view.H - 14;
    ctx.strokeStyle = "#333";
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.moveTo(x0, y0 - 4); ctx.lineTo(x0, y0); ctx.lineTo(x0 + px, y0); ctx.lineTo(x0 + px, y0 - 4);
    ctx.stroke();
    ctx.fillStyle = "#333";
    ctx.font = "11px sans-serif";
    ctx.textAlign = "center";
    ctx.fillText(fmt(len) + " m", x0 + px / 2, y0 - 5);
    ctx.textAlign = "left";
  }

  // zoom (wheel, about the pointer) and pan (drag)
  wrap.addEventListener("wheel", function (ev) {
    ev.preventDefault();
    const rect = map.getBoundingClientRect();
    const px = ev.clientX - rect.left;
    const py = ev.clientY - rect.top;
    const before = c2w(px, py);
    const delta = ev.deltaMode === 1 ? ev.deltaY * 16 : ev.deltaY;
    view.scale *= Math.exp(-delta * 0.0015);
    view.scale = Math.min(Math.max(view.scale, 1e-6), 1e6);
    const after = c2w(px, py);
    view.cx += before[0] - after[0];
    view.cy += before[1] - after[1];
    view.user = true;
    render();
  }, { passive: false });
  let drag = null;
  wrap.addEventListener("pointerdown", function (ev) {
    if (ev.button !== 0) return;
    drag = { x: ev.clientX, y: ev.clientY, cx: view.cx, cy: view.cy };
    wrap.setPointerCapture(ev.pointerId);
    wrap.classList.add("dragging");
  });
  wrap.addEventListener("pointermove", function (ev) {
    if (!drag) return;
    view.cx = drag.cx - (ev.clientX - drag.x) / view.scale;
    view.cy = drag.cy + (ev.clientY - drag.y) / view.scale;
    view.user = true;
    render();
  });
  function endDrag() { drag = null; wrap.classList.remove("dragging"); }
  wrap.addEventListener("pointerup", endDrag);
  wrap.addEventListener("pointercancel", endDrag);

  // -- time plots -----------------------------------------------------------------------
  function oneOrEach(key, each) { // the groups' common label, or a word for all of them
    const labels = new Set(groups.map(function (g) { return g[key]; }));
    return labels.size === 1 ? groups[0][key] : each;
  }
  const PLOTS = [
    { key: "crlb", title: "CRLB (m²); dashed: " + oneOrEach("boundLabel", "each group's bound"), log: true },
    { key: "cost", title: "control cost L_tot, eq. (15)", log: true },
    { key: "eta", title: "scaling η", log: false, fixed: [0, 1.05] },
    { key: "clearance", title: "min clearance (m); dotted: safety radius", log: false,
      line: D.safetyRadius },
    { key: "separation", title: "min separation (m); dotted: minimum", log: false,
      line: D.minSeparation },
  ];
  const PAD = { l: 48, r: 8, t: 6, b: 17 };
  const plotsDiv = document.getElementById("plots");
  for (const p of PLOTS) {
    const box = document.createElement("div");
    box.className = "plot";
    const head = document.createElement("div");
    head.className = "plot-title";
    const name = document.createElement("span");
    name.textContent = p.title;
    p.value = document.createElement("span");
    head.appendChild(name);
    head.appendChild(p.value);
    p.canvas = document.createElement("canvas");
    p.canvas.id = "plot-" + p.key;
    box.appendChild(head);
    box.appendChild(p.canvas);
    plotsDiv.appendChild(box);
    p.layer = document.createElement("canvas");
    p.stale = true;
    const seek = function (ev) {
      const rect = p.canvas.getBoundingClientRect();
      api.setTime(xToTime(p, ev.clientX - rect.left));
    };
    p.canvas.addEventListener("pointerdown", function (ev) {
      p.canvas.setPointerCapture(ev.pointerId);
      p.seeking = true;
      seek(ev);
    });
    p.canvas.addEventListener("pointermove", function (ev) { if (p.seeking) seek(ev); });
    p.canvas.addEventListener("pointerup", function () { p.seeking = false; });
  }
  function xToTime(p, x) {
    const w = p.W - PAD.l - PAD.r;
    return T[0] + (T[F - 1] - T[0]) * Math.min(Math.max((x - PAD.l) / w, 0), 1);
  }
  function timeToX(p, t) {
    const span = T[F - 1] - T[0] || 1;
    return PAD.l + (p.W - PAD.l - PAD.r) * (t - T[0]) / span;
  }
  function plotRange(p) {
    if (p.fixed) return p.fixed;
    let lo = Infinity;
    let hi = -Infinity;
    const take = function (v) {
      if (!isFinite(v) || (p.log && v <= 0)) return;
      lo = Math.min(lo, v); hi = Math.max(hi, v);
    };
    groups.forEach(function (g) {
      const s = g.series[p.key];
      for (let i = 0; i < S; i++) take(s[state.run * S + i]);
      const env = g.envelope[p.key];
      if (env) for (let i = 0; i < 2 * S; i++) take(env[i]);
      if (p.key === "crlb") take(g.bound);
    });
    if (!isFinite(lo)) return null;
    if (p.line !== undefined && isFinite(p.line)) take(p.line);
    if (p.log) {
      let a = Math.log10(lo);
      let b = Math.log10(hi);
      if (b - a < 0.3) { a -= 0.15; b += 0.15; }
      const pad = 0.05 * (b - a);
      return [a - pad, b + pad];
    }
    if (p.key !== "eta") lo = Math.min(lo, 0);
    if (hi - lo < 1e-9) { hi += 1; lo -= 1; }
    return [lo, hi + 0.06 * (hi - lo)];
  }
  function yOf(p, v) {
    const u = p.log ? Math.log10(v) : v;
    return PAD.t + (p.H - PAD.t - PAD.b) * (1 - (u - p.range[0]) / (p.range[1] - p.range[0]));
  }
  function seriesLine(ctx, p, arr, off) {
    ctx.beginPath();
    let on = false;
    for (let i = 0; i < S; i++) {
      const v = arr[off + i];
      if (!isFinite(v) || (p.log && v <= 0)) { on = false; continue; }
      const x = timeToX(p, TS[i]);
      const y = yOf(p, v);
      if (on) ctx.lineTo(x, y); else { ctx.moveTo(x, y); on = true; }
    }
  }
  function yTicks(p) {
    const a = p.range[0];
    const b = p.range[1];
    const out = [];
    if (p.log) {
      const every = Math.max(1, Math.ceil((Math.floor(b) - Math.ceil(a) + 1) / 4));
      for (let e = Math.ceil(a); e <= b; e += every) out.push(Math.pow(10, e));
      if (out.length < 2) out.splice(0, out.length, Math.pow(10, a + 0.1 * (b - a)), Math.pow(10, b - 0.1 * (b - a)));
      return out;
    }
    const step = niceStep((b - a) / 3.5);
    for (let v = Math.ceil(a / step) * step; v <= b + 1e-12; v += step) out.push(v);
    return out;
  }
  function drawPlotLayer(p) {
    const dpr = window.devicePixelRatio || 1;
    p.layer.width = p.canvas.width;
    p.layer.height = p.canvas.height;
    const ctx = p.layer.getContext("2d");
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.fillStyle = "#fff";
    ctx.fillRect(0, 0, p.W, p.H);
    p.range = plotRange(p);
    ctx.font = "10px sans-serif";
    ctx.fillStyle = "#666";
    if (p.range === null) {
      ctx.textAlign = "center";
      ctx.fillText(p.key === "clearance" ? "no obstacles" : "no finite values", p.W / 2, p.H / 2);
      p.stale = false;
      return;
    }
    ctx.strokeStyle = "#e6e6e6";
    ctx.lineWidth = 1;
    ctx.textAlign = "right";
    for (const v of yTicks(p)) {
      const y = Math.round(yOf(p, v)) + 0.5;
      ctx.beginPath(); ctx.moveTo(PAD.l, y); ctx.lineTo(p.W - PAD.r, y); ctx.stroke();
      ctx.fillText(fmt(v), PAD.l - 4, y + 3);
    }
    ctx.textAlign = "center";
    const tstep = niceStep((T[F - 1] - T[0]) / 6 || 1);
    for (let t = Math.ceil(T[0] / tstep) * tstep; t <= T[F - 1] + 1e-9; t += tstep) {
      const x = Math.round(timeToX(p, t)) + 0.5;
      ctx.beginPath(); ctx.moveTo(x, PAD.t); ctx.lineTo(x, p.H - PAD.b); ctx.stroke();
      ctx.fillText(fmt(t) + (t + tstep > T[F - 1] + 1e-9 ? " s" : ""), x, p.H - 5);
    }
    ctx.strokeStyle = "#999";
    ctx.strokeRect(PAD.l + 0.5, PAD.t + 0.5, p.W - PAD.l - PAD.r - 1, p.H - PAD.t - PAD.b - 1);
    ctx.save();
    ctx.beginPath();
    ctx.rect(PAD.l, PAD.t, p.W - PAD.l - PAD.r, p.H - PAD.t - PAD.b);
    ctx.clip();
    groups.forEach(function (g, gi) {
      const env = g.envelope[p.key];
      if (env) { // the batch: min..max over the runs
        ctx.beginPath();
        let on = false;
        for (let i = 0; i < S; i++) {
          const v = env[S + i];
          if (!isFinite(v) || (p.log && v <= 0)) continue;
          const x = timeToX(p, TS[i]);
          if (on) ctx.lineTo(x, yOf(p, v)); else { ctx.moveTo(x, yOf(p, v)); on = true; }
        }
        for (let i = S - 1; i >= 0; i--) {
          const v = env[i];
          if (!isFinite(v) || (p.log && v <= 0)) continue;
          ctx.lineTo(timeToX(p, TS[i]), yOf(p, v));
        }
        ctx.closePath();
        ctx.fillStyle = groups.length > 1 ? groupColour(gi) + "22" : "rgba(0,0,0,0.09)";
        ctx.fill();
      }
    });
    const lineAt = function (v, colour, dash) {
      if (v === undefined || !isFinite(v) || (p.log && v <= 0)) return;
      const y = yOf(p, v);
      ctx.setLineDash(dash);
      ctx.strokeStyle = colour;
      ctx.lineWidth = 1.2;
      ctx.beginPath(); ctx.moveTo(PAD.l, y); ctx.lineTo(p.W - PAD.r, y); ctx.stroke();
      ctx.setLineDash([]);
    };
    if (p.key === "crlb") groups.forEach(function (g, gi) { lineAt(g.bound, groups.length > 1 ? groupColour(gi) : "#111", [5, 4]); });
    lineAt(p.line, "#555", [2, 3]);
    groups.forEach(function (g, gi) {
      ctx.strokeStyle = groupColour(gi);
      ctx.lineWidth = 1.5;
      seriesLine(ctx, p, g.series[p.key], state.run * S);
      ctx.stroke();
    });
    ctx.restore();
    p.stale = false;
  }
  function resizePlots() {
    const dpr = window.devicePixelRatio || 1;
    for (const p of PLOTS) {
      const r = p.canvas.getBoundingClientRect();
      p.W = Math.max(60, Math.floor(r.width));
      p.H = Math.max(40, Math.floor(r.height));
      p.canvas.width = Math.round(p.W * dpr);
      p.canvas.height = Math.round(p.H * dpr);
      p.stale = true;
    }
  }
  function drawPlots() {
    const dpr = window.devicePixelRatio || 1;
    for (const p of PLOTS) {
      if (p.stale) drawPlotLayer(p);
      const ctx = p.canvas.getContext("2d");
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      ctx.drawImage(p.layer, 0, 0);
      ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
      const x = timeToX(p, state.time);
      ctx.strokeStyle = "#d62728";
      ctx.lineWidth = 1.3;
      ctx.beginPath(); ctx.moveTo(x, PAD.t); ctx.lineTo(x, p.H - PAD.b); ctx.stroke();
      const values = groups.map(function (g) { return seriesAt(g, p.key, state.run, state.time); });
      if (p.range) {
        values.forEach(function (v, gi) {
          if (!isFinite(v) || (p.log && v <= 0)) return;
          ctx.fillStyle = groupColour(gi);
          ctx.beginPath(); ctx.arc(x, yOf(p, v), 3, 0, 2 * Math.PI); ctx.fill();
        });
      }
      p.value.textContent = values.map(fmt).join(" · ") + (p.key === "crlb" && groups.length === 1
        ? " (" + fmt(values[0] / groups[0].bound) + "× bound)" : "");
    }
  }

  // -- text -----------------------------------------------------------------------------
  const el = function (id) { return document.getElementById(id); };
  const slider = el("slider");
  const runSelect = el("run");
  const playButton = el("play");
  const speedSelect = el("speed");

  function setupText() {
    el("title").textContent = D.title;
    el("subtitle").textContent = D.description;
    const dec = D.decimation;
    const every = function (n, what) { return n === 1 ? "every " + what : "every " + n + " " + what + "s"; };
    el("note").textContent = "Map: " + dec.frames + " frames per run, at " + every(dec.frameStride, "kept step") +
      " of " + dec.keptSteps + " (trajectories kept at " + every(dec.trajectoryStride, "step") +
      " of " + D.step + " s) and at the last; between frames the map interpolates linearly. " +
      "Time plots: " + dec.seriesPoints + " points per run, at " + every(dec.seriesStride, "step") +
      " of " + (D.steps + 1) + " and at the last, whatever the trajectories kept: the CRLB, cost " +
      "and η at those steps, the clearance and separation as their smallest since the previous " +
      "point. At most " + dec.maxFrames + " frames (and points) per run and " + dec.maxMB +
      " MB of data. The run panel's figures are over every step" +
      (NR > 1 ? "; grey band: smallest to largest over the " + NR + " runs" : "") + ". " +
      D.generator + ".";
    slider.max = String(F - 1);
    for (let r = 0; r < NR; r++) {
      const o = document.createElement("option");
      o.value = String(r);
      const outcomes = groups.map(function (g) { return g.metrics.outcome[r]; });
      o.textContent = "run " + D.runIndex[r] + " · seed " + D.seed[r] + " · " + outcomes.join("/");
      runSelect.appendChild(o);
    }
    runSelect.disabled = NR < 2;
    const legend = el("legend");
    const item = function (swatch, text) {
      const d = document.createElement("div");
      const i = document.createElement("i");
      i.style.cssText = swatch;
      const s = document.createElement("span");
      s.textContent = text;
      d.appendChild(i); d.appendChild(s);
      legend.appendChild(d);
    };
    item("background:" + LEADER + ";border-radius:5px;width:10px", "leader" + (groups.length > 1 ? "s" : ""));
    const followers = UAV_COLOURS.filter(function (c, u) { return !LEADERS.has(u); }).slice(0, 8);
    if (followers.length) item("background:linear-gradient(90deg," + followers.join(",") + ")", "followers");
    item("border-top:1.5px solid #222;height:0", "formation");
    item("border-top:1.5px dashed #d62728;height:0", oneOrEach("formationLabel", "each group's formation over its target"));
    item("background:#111;clip-path:polygon(50% 0,61% 35%,98% 35%,68% 57%,79% 91%,50% 70%,21% 91%,32% 57%,2% 35%,39% 35%);width:12px;height:12px", "target");
    if (groups.some(function (g) { return g.estimate; })) item("border-top:2px solid #c80078;height:0;width:12px", "estimate (×)");
    if (D.obstacles.rectangles.length + D.obstacles.circles.length) item("background:rgba(128,128,128,0.78)", "obstacle");
  }
  function updateText() {
    const fr = frameAt(state.time);
    const r = state.run;
    el("time-label").textContent = "t = " + state.time.toFixed(1) + " s / " + T[F - 1].toFixed(1) +
      " s · frame " + (fr.i + 1) + "/" + F;
    const eta = groups.map(function (g) { return fmt(seriesAt(g, "eta", r, state.time)); }).join(", ");
    el("map-overlay").textContent = "t = " + state.time.toFixed(1) + " s   η = " + eta;
    const rows = [["run", D.runIndex[r] + " (seed " + D.seed[r] + ")"]];
    groups.forEach(function (g, gi) {
      const pre = groups.length > 1 ? "group " + gi + ": " : "";
      const m = g.metrics;
      rows.push([pre + "outcome", m.outcome[r]]);
      // (a time only for a run whose outcome is converged: a collided run may have settled)
      rows.push([pre + "convergence time", m.outcome[r] !== "converged" ? "– (not converged)"
        : m.convergence_time_s[r] === null ? "–" : fmt(m.convergence_time_s[r]) + " s"]);
      rows.push([pre + "final CRLB / bound", fmt(m.final_crlb_ratio[r])]);
      rows.push([pre + "min clearance (every step)", m.min_clearance_m[r] === null ? "no obstacles" : fmt(m.min_clearance_m[r]) + " m"]);
      rows.push([pre + "min separation (every step)", fmt(m.min_separation_m[r]) + " m"]);
    });
    const cells = [];
    for (const row of rows) {
      for (const text of row) {
        const span = document.createElement("span");
        span.textContent = String(text);
        cells.push(span);
      }
    }
    el("info").replaceChildren.apply(el("info"), cells);
  }

  // -- the loop ---------------------------------------------------------------------------
  let infoRun = -1;
  function render() {
    drawMap();
    drawPlots();
    const fr = frameAt(state.time);
    slider.value = String(fr.w > 0.999999 ? fr.i + 1 : fr.i);
    if (infoRun !== state.run) { updateText(); infoRun = state.run; } else {
      const r = state.run;
      el("time-label").textContent = "t = " + state.time.toFixed(1) + " s / " + T[F - 1].toFixed(1) +
        " s · frame " + (fr.i + 1) + "/" + F;
      el("map-overlay").textContent = "t = " + state.time.toFixed(1) + " s   η = " +
        groups.map(function (g) { return fmt(seriesAt(g, "eta", r, state.time)); }).join(", ");
    }
  }
  function tick(now) {
    if (!state.playing) return;
    if (state.last !== null) {
      const dt = Math.min((now - state.last) / 1000, 0.25);
      state.time = Math.min(state.time + dt * state.speed, T[F - 1]);
    }
    state.last = now;
    if (state.time >= T[F - 1]) { api.pause(); render(); return; }
    render();
    requestAnimationFrame(tick);
  }
  function setButton() {
    playButton.textContent = state.playing ? "❚❚ Pause" : "▶ Play";
    playButton.setAttribute("aria-pressed", String(state.playing));
  }

  const api = {
    nRuns: NR,
    nFrames: F,
    nSeriesPoints: S,
    nUavs: NU,
    duration: T[F - 1],
    data: D,
    time: function () { return state.time; },
    setTime: function (t) {
      const v = Number(t);
      if (!isFinite(v)) throw new Error("setTime: not a number: " + t);
      state.time = Math.min(Math.max(v, T[0]), T[F - 1]);
      render();
      return state.time;
    },
    frame: function () { return frameAt(state.time).i; },
    frameTimes: function () { return T.slice(); },
    seriesTimes: function () { return TS.slice(); },
    setFrame: function (i) { return api.setTime(T[Math.min(Math.max(Math.round(i), 0), F - 1)]); },
    run: function () { return state.run; },
    runIndex: function () { return D.runIndex[state.run]; },
    setRun: function (i) {
      const r = Number(i);
      if (!Number.isInteger(r) || r < 0 || r >= NR) throw new Error("setRun: no run " + i + " (0.." + (NR - 1) + ")");
      state.run = r;
      runSelect.value = String(r);
      for (const p of PLOTS) p.stale = true;
      if (!view.user) fitView();
      render();
      return r;
    },
    play: function () {
      if (state.playing) return;
      if (state.time >= T[F - 1]) state.time = T[0];
      state.playing = true;
      state.last = null;
      setButton();
      requestAnimationFrame(tick);
    },
    pause: function () { state.playing = false; state.last = null; setButton(); },
    playing: function () { return state.playing; },
    speed: function () { return state.speed; },
    setSpeed: function (s) {
      const v = Number(s);
      if (!(v > 0)) throw new Error("setSpeed: must be > 0");
      state.speed = v;
      speedSelect.value = String(v);
      return v;
    },
    uavPositions: function () {
      const fr = frameAt(state.time);
      const out = new Array(NU);
      for (const g of groups) for (let m = 0; m < g.M; m++) out[g.uavs[m]] = uavAt(g, state.run, m, fr);
      return out;
    },
    targetPositions: function () {
      const fr = frameAt(state.time);
      return groups.map(function (g) { return targetAt(g, state.run, fr); });
    },
    estimatePositions: function () {
      const fr = frameAt(state.time);
      return groups.map(function (g) { return estimateAt(g, state.run, fr); });
    },
    seriesValues: function () {
      const out = {};
      for (const name of SERIES) out[name] = groups.map(function (g) { return seriesAt(g, name, state.run, state.time); });
      return out;
    },
    uavColours: function () { return UAV_COLOURS.slice(); },
    leaders: function () { return groups.map(function (g) { return g.leader; }); },
    worldToCanvas: function (x, y) { return w2c(x, y); },
    canvasToWorld: function (px, py) { return c2w(px, py); },
    view: function () { return { cx: view.cx, cy: view.cy, scale: view.scale, width: view.W, height: view.H }; },
    resetView: function () { fitView(); render(); },
  };

  // -- wiring -----------------------------------------------------------------------------
  playButton.addEventListener("click", function () { if (state.playing) api.pause(); else api.play(); });
  speedSelect.addEventListener("change", function () { state.speed = Number(speedSelect.value); });
  slider.addEventListener("input", function () { api.setFrame(Number(slider.value)); });
  runSelect.addEventListener("change", function () { api.setRun(Number(runSelect.value)); });
  el("reset-view").addEventListener("click", function () { api.resetView(); });
  document.addEventListener("keydown", function (ev) {
    const tag = ev.target && ev.target.tagName;
    if (tag === "SELECT" || tag === "INPUT") return;
    if (ev.key === " ") { ev.preventDefault(); if (state.playing) api.pause(); else api.play(); }
    else if (ev.key === "ArrowRight") api.setFrame(api.frame() + 1);
    else if (ev.key === "ArrowLeft") api.setFrame(frameAt(state.time).w > 0 ? api.frame() : api.frame() - 1);
  });
  function resize() { resizeMap(); resizePlots(); render(); }
  setupText();
  window.addEventListener("resize", resize);
  resize();
  window.crlbReplay = Object.freeze(api);
  document.body.dataset.ready = "1";
})();
