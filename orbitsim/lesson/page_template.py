"""The HTML, CSS and JavaScript of ``lesson.html`` (:mod:`orbitsim.lesson.page` fills in
``__LESSON_DATA__``). Everything is inline: the page works from a file, offline, with no CDN.

The script plays precomputed orbitsim runs; it integrates nothing. Its animation loop is the
fixed-timestep loop of ``orbitsim animate``: each drawn frame adds its elapsed time (times the
playback speed) to an accumulator, takes whole steps of the run's dt while the accumulator holds
at least dt, and draws the planet interpolated by alpha = accumulator / dt between the last two
states. ``window.lesson`` exposes the loop for the browser test (``tests/lesson/test_lesson_browser.py``).
"""

PAGE_TEMPLATE = r"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>orbitsim: one orbit, three ways to step time (play)</title>
<style>
body { font-family: system-ui, sans-serif; margin: 1.2em auto; max-width: 1100px; color: #222; padding: 0 1em; }
h1 { font-size: 1.5em; margin-bottom: 0.2em; } h3 { margin: 0.2em 0; }
.controls { display: flex; flex-wrap: wrap; gap: 1.5em; align-items: center; background: #f4f4f4;
            padding: 0.7em 1em; border-radius: 6px; margin: 0.8em 0; }
.controls label { font-weight: 600; margin-right: 0.4em; }
.panels { display: grid; grid-template-columns: repeat(3, 1fr); gap: 1em; }
.panel { border: 1px solid #ddd; border-radius: 6px; padding: 0.5em; background: #fff; }
.panel canvas { width: 100%; display: block; }
.moral { font-size: 0.85em; color: #555; min-height: 2.4em; margin: 0.2em 0; }
.energy { font-family: ui-monospace, monospace; font-size: 0.85em; }
.answer-row { display: grid; grid-template-columns: 1.1fr 1fr; gap: 1.2em; margin-top: 1.2em; align-items: start; }
.answer { background: #fff7e6; border-left: 4px solid #d62728; padding: 0.6em 1em; }
#clock { font-family: ui-monospace, monospace; }
</style></head>
<body>
<h1>One orbit, three ways to step time</h1>
<p>The same planet on the same e = 0.3 orbit, stepped by three schemes that differ only in the order of
their two updates. Every state below was computed by orbitsim (<code>orbitsim demo</code>) and is
embedded in this page; the page only plays it back. Move <b>dt</b> to switch between runs at other
timesteps, and the <b>frame rate</b> to change how often the page draws.</p>
<div class="controls">
  <span><label for="dt">dt</label><input type="range" id="dt" min="0" step="1">
    <span id="dt-label"></span></span>
  <span><label for="fps">frame rate</label><select id="fps">
    <option value="5">5 fps</option><option value="10">10 fps</option><option value="24">24 fps</option>
    <option value="30" selected>30 fps</option><option value="60">60 fps</option></select></span>
  <button id="play" type="button">pause</button>
  <span id="clock"></span>
</div>
<div class="panels" id="panels"></div>
<div class="answer-row">
  <div class="panel"><h3>Explicit Euler's energy, at every dt</h3>
    <canvas id="euler-climb" width="560" height="260"></canvas>
    <div class="moral">Red: explicit Euler at each dt of the slider (bold: the one selected). Orange,
      dashed: semi-implicit Euler at the largest dt.</div></div>
  <div class="answer" id="answer"><h3>Your orbit spirals out: what is the fix?</h3>
    <p><b>Change the update order, not dt.</b> Explicit Euler drifts with the <i>old</i> velocity and
    kicks with the old acceleration, so every step adds energy and the orbit spirals out. A smaller dt
    only slows the climb (left: every red curve still climbs, at four times the cost for a quarter of
    the step).</p>
    <p>Kick first, then drift with the <i>new</i> velocity: that is semi-implicit Euler, one line
    swapped, the same cost per step, and it is symplectic: its energy error stays in a band and
    never climbs, even at four times the lesson's dt (dashed). Velocity Verlet splits the kick around
    the drift and narrows the band further.</p></div>
</div>
<h3 style="margin-top:1.2em">How this page animates</h3>
<p>The physics runs in fixed steps of dt; the page draws at its own frame rate. Each frame adds the
time that passed to an accumulator, takes whole physics steps while the accumulator holds at least
dt, and draws the planet interpolated by alpha = accumulator / dt between the last two states. The
solid line is the physics states; the black dots are the frames drawn. Change the frame rate: the dots
thin out or crowd, the orbit stays the same. The same loop renders <code>orbitsim animate</code>.</p>
<script id="lesson-data" type="application/json">__LESSON_DATA__</script>
<script>
"use strict";
const D = JSON.parse(document.getElementById("lesson-data").textContent);
const S = D.schemes;
const view = { idx: D.lesson_index, fps: 30, playing: true };
const clock = { acc: 0, steps: 0, frames: 0, last: null, marks: [] };
const MAX_MARKS = 40;     // frames marked on the orbit: enough to see their spacing
const MAX_FRAME_S = 0.25; // a stalled tab must not replay seconds at once

function run(key, i) { return D.runs[key][i === undefined ? view.idx : i]; }
function lastStep(i) { return run(S[0].key, i).x.length - 1; }

// The fixed-timestep loop: pure, so the test can drive it with any frame times.
function advance(c, elapsed, dt, n) {
  c.acc += elapsed;
  while (c.acc >= dt && c.steps < n) { c.acc -= dt; c.steps += 1; }
  if (c.steps >= n) c.acc = 0;  // the run's last state: hold it
  return c;
}
function drawn(c, key, i) {  // the state between the last two physics states
  const r = run(key, i), dt = D.dts[i === undefined ? view.idx : i];
  const cur = c.steps, prev = Math.max(cur - 1, 0), a = cur > 0 ? c.acc / dt : 0;
  return { x: r.x[prev] + a * (r.x[cur] - r.x[prev]), y: r.y[prev] + a * (r.y[cur] - r.y[prev]),
           t: cur > 0 ? (prev + a) * dt : 0, steps: cur, alpha: a };
}
function stateAt(fps, seconds, key, i) {  // what the loop shows after `seconds` at `fps`
  const c = { acc: 0, steps: 0 }, n = lastStep(i), dt = D.dts[i];
  for (let k = 0; k < Math.round(seconds * fps); k++) advance(c, D.speed / fps, dt, n);
  return drawn(c, key, i);
}

function toPx(cv, x, y) {
  const s = cv.width / (2 * D.extent);
  return [cv.width / 2 + x * s, cv.height / 2 - y * s];
}
function polyline(ctx, cv, xs, ys, n) {
  ctx.beginPath();
  for (let k = 0; k <= n && k < xs.length; k++) {
    const [px, py] = toPx(cv, xs[k], ys[k]);
    if (k === 0) ctx.moveTo(px, py); else ctx.lineTo(px, py);
  }
  ctx.stroke();
}
function drawOrbit(sc) {
  const cv = document.getElementById("orbit-" + sc.key), ctx = cv.getContext("2d"), r = run(sc.key);
  ctx.clearRect(0, 0, cv.width, cv.height);
  ctx.lineWidth = 6; ctx.strokeStyle = "rgba(120,120,120,0.25)";
  polyline(ctx, cv, D.reference.x, D.reference.y, D.reference.x.length);
  ctx.lineWidth = 1; ctx.strokeStyle = sc.color; ctx.globalAlpha = 0.18;
  polyline(ctx, cv, r.x, r.y, r.x.length);   // where this run goes: changes with dt
  ctx.globalAlpha = 1; ctx.lineWidth = 1.6;
  const p = drawn(clock, sc.key);
  polyline(ctx, cv, r.x, r.y, Math.max(clock.steps - 1, 0));  // the physics states so far
  ctx.fillStyle = "#222";
  for (const m of clock.marks) {
    const [mx, my] = toPx(cv, m[sc.key].x, m[sc.key].y);
    ctx.fillRect(mx - 1, my - 1, 2, 2);
  }
  const [sx, sy] = toPx(cv, 0, 0);
  ctx.fillStyle = "#e6a700"; ctx.beginPath(); ctx.arc(sx, sy, 7, 0, 2 * Math.PI); ctx.fill();
  const [px, py] = toPx(cv, p.x, p.y);
  ctx.fillStyle = sc.color; ctx.beginPath(); ctx.arc(px, py, 5, 0, 2 * Math.PI); ctx.fill();
  cv.dataset.x = p.x.toFixed(6); cv.dataset.y = p.y.toFixed(6);
}
function drawEnergy(sc) {
  const cv = document.getElementById("energy-plot-" + sc.key), ctx = cv.getContext("2d"), r = run(sc.key);
  const lo = Math.min(0, ...r.e), hi = Math.max(0, ...r.e), span = (hi - lo) || 1, n = r.e.length - 1;
  const X = k => 4 + (cv.width - 8) * k / n, Y = e => cv.height - 6 - (cv.height - 12) * (e - lo) / span;
  ctx.clearRect(0, 0, cv.width, cv.height);
  ctx.strokeStyle = "#bbb"; ctx.lineWidth = 1;
  ctx.beginPath(); ctx.moveTo(X(0), Y(0)); ctx.lineTo(X(n), Y(0)); ctx.stroke();
  ctx.strokeStyle = sc.color; ctx.lineWidth = 1.3; ctx.beginPath();
  for (let k = 0; k <= n; k++) { if (k) ctx.lineTo(X(k), Y(r.e[k])); else ctx.moveTo(X(k), Y(r.e[k])); }
  ctx.stroke();
  ctx.strokeStyle = "#222";
  ctx.beginPath(); ctx.moveTo(X(clock.steps), 0); ctx.lineTo(X(clock.steps), cv.height); ctx.stroke();
  const peak = Math.max(...r.e.map(Math.abs));
  document.getElementById("energy-" + sc.key).textContent =
    "dE/E now " + r.e[clock.steps].toExponential(2) + ", max |dE/E| " + peak.toExponential(2);
}
function drawClimb() {
  const cv = document.getElementById("euler-climb"), ctx = cv.getContext("2d");
  const curves = D.runs[S[0].key].map((r, i) => ({ e: r.e, dt: D.dts[i], color: S[0].color, bold: i === view.idx }));
  const last = D.dts.length - 1;
  curves.push({ e: D.runs[S[1].key][last].e, dt: D.dts[last], color: S[1].color, dash: true });
  const tEnd = D.dts[0] * (curves[0].e.length - 1);
  const hi = Math.max(...curves.map(c => Math.max(...c.e))), lo = Math.min(0, ...curves.map(c => Math.min(...c.e)));
  const X = t => 40 + (cv.width - 50) * t / tEnd, Y = e => cv.height - 22 - (cv.height - 32) * (e - lo) / (hi - lo);
  ctx.clearRect(0, 0, cv.width, cv.height);
  ctx.fillStyle = "#444"; ctx.font = "11px sans-serif";
  ctx.fillText("dE/E (top of the axis: " + hi.toExponential(1) + ")", 44, 10); ctx.fillText("0", 24, Y(0) + 4);
  ctx.fillText("time [" + D.time_unit + "]", cv.width - 120, cv.height - 4);
  for (const c of curves) {
    ctx.strokeStyle = c.color; ctx.lineWidth = c.bold ? 2.6 : 1; ctx.setLineDash(c.dash ? [6, 4] : []);
    ctx.beginPath();
    c.e.forEach((e, k) => { const x = X(k * c.dt), y = Y(e); if (k) ctx.lineTo(x, y); else ctx.moveTo(x, y); });
    ctx.stroke();
  }
  ctx.setLineDash([]);
}
function render() {
  S.forEach(sc => { drawOrbit(sc); drawEnergy(sc); });
  const dt = D.dts[view.idx], p = drawn(clock, S[0].key);
  document.getElementById("clock").textContent = "t = " + p.t.toFixed(2) + " " + D.time_unit +
    " | physics steps " + clock.steps + " | frames drawn " + clock.frames + " | alpha " + p.alpha.toFixed(2);
  document.getElementById("dt-label").textContent = "dt = " + dt.toPrecision(3) + " (" + D.factors[view.idx] +
    "x the lesson's, " + Math.round(D.steps_per_orbit[view.idx]) + " steps per orbit)";
}
function restart() { clock.acc = 0; clock.steps = 0; clock.frames = 0; clock.last = null; clock.marks = []; }
function tick(now) {
  requestAnimationFrame(tick);
  if (!view.playing) return;
  if (clock.last !== null && now - clock.last < 1000 / view.fps - 1) return;  // the page's frame rate
  const elapsed = clock.last === null ? 0 : Math.min((now - clock.last) / 1000, MAX_FRAME_S);
  clock.last = now;
  if (clock.steps >= lastStep()) restart();
  advance(clock, elapsed * D.speed, D.dts[view.idx], lastStep());
  clock.frames += 1;
  const mark = {};
  S.forEach(sc => { mark[sc.key] = drawn(clock, sc.key); });
  clock.marks.push(mark);
  if (clock.marks.length > MAX_MARKS) clock.marks.shift();
  render(); drawClimb();
}
function build() {
  const box = document.getElementById("panels");
  for (const sc of S) {
    const div = document.createElement("div");
    div.className = "panel";
    div.innerHTML = "<h3 style='color:" + sc.color + "'>" + sc.title + "</h3><div class='moral'>" + sc.moral +
      "</div><canvas id='orbit-" + sc.key + "' width='340' height='340'></canvas>" +
      "<canvas id='energy-plot-" + sc.key + "' width='340' height='110'></canvas>" +
      "<div class='energy' id='energy-" + sc.key + "'></div>";
    box.appendChild(div);
  }
  const slider = document.getElementById("dt");
  slider.max = D.dts.length - 1; slider.value = view.idx;
  slider.addEventListener("input", () => { view.idx = Number(slider.value); restart(); render(); drawClimb(); });
  document.getElementById("fps").addEventListener("change", e => {
    view.fps = Number(e.target.value); clock.marks = [];
  });
  document.getElementById("play").addEventListener("click", e => {
    view.playing = !view.playing; clock.last = null; e.target.textContent = view.playing ? "pause" : "play";
  });
  render(); drawClimb(); requestAnimationFrame(tick);
}
window.lesson = { data: D, view, clock, advance, drawn, stateAt, render };
build();
</script>
</body></html>
"""
