// The kappa-planner viewer: loads a planning request (the demo, an example of the API docs, a file,
// pasted JSON, ?request=URL), plans it through POST /v1/plan with return_candidates and draws it;
// or plays back a simulator run file (?run=URL, a dropped run.json.gz) cycle by cycle.
//
// For browser tests the page exposes what it drew: document.body.dataset.planStatus (the plan's
// status, "ok" for a coordinate conversion, "error" on failure with dataset.planError the error
// code), dataset.view, dataset.folds; the map's dataset.candidates, .foldsAlg4, .trajectoryPoints,
// .obstacles, .time; run playback: dataset.runCycles and dataset.cycle.

import { ApiError, getJson, parseDocument, parseJson, post, setApiKey } from "./api.js";
import {
  bandQuads, bounds, boxCorners, curveAt, foldsBack, interp, obstacleKind, offsetCurve, predictionAt,
  referenceCurve, trajectoryAt, widthsAlong,
} from "./geometry.js";
import { MapView, el, pathData } from "./map.js";
import { Plot } from "./plots.js";
import { RUN_FORMAT, cycleAt, cycleData, decodeRun } from "./runfile.js";
import { num, tree } from "./tree.js";

const $ = (id) => document.getElementById(id);
const body = document.body;
const map = new MapView($("map"));
const plots = {
  v: new Plot($("plot-v"), { title: "v(t) [m/s]" }),
  a: new Plot($("plot-a"), { title: "a(t) [m/s²]" }),
  kappa: new Plot($("plot-kappa"), { title: "κ(s) [1/m]" }),
  d: new Plot($("plot-d"), { title: "d(s) [m]" }),
};

//: defaults of the API's vehicle (replaced by the OpenAPI document's when it is served)
const defaults = { length: 4.5, width: 1.8, max_speed: 20, max_acceleration: 2, max_deceleration: 6, max_curvature: 0.2 };
//: most points of one POST /v1/frenet (the API's limit, read from the OpenAPI document when served)
let frenetLimit = 10000;
//: most candidate points the fold test sends to /v1/frenet (in chunks of frenetLimit)
const MAX_FOLD_POINTS = 100000;

const state = {
  token: 0,
  controller: null,
  view: null, // "plan" | "run" | "frenet" | "cartesian"
  request: null,
  road: null, // {curve, left, right, roadLeft, roadRight}
  answer: null,
  trajectory: null, // {t, x, y, heading, v, a, s, d, curvature} arrays
  run: null,
  t: 0,
  tMax: 0,
  playing: false,
  vScale: [0, 1],
  obstacleNodes: [],
};

// ------------------------------------------------------------------------------------------------
// Status, errors, summary, diagnostics
// ------------------------------------------------------------------------------------------------

function setBadge(text, kind) {
  const badge = $("badge");
  badge.textContent = text;
  badge.dataset.state = kind;
}

function resetStatus() {
  delete body.dataset.planStatus;
  delete body.dataset.planError;
  delete body.dataset.folds;
  delete body.dataset.runCycles;
  delete body.dataset.cycle;
  $("error").hidden = true;
  $("error").replaceChildren();
}

function showError(err, context) {
  const box = $("error");
  box.replaceChildren();
  const code = err instanceof ApiError ? err.code : "viewer_error";
  const title = document.createElement("h3");
  title.textContent = `${context}: ${code}${err.status ? ` (HTTP ${err.status})` : ""}`;
  const message = document.createElement("div");
  message.className = "error-message";
  message.textContent = err.message || String(err);
  box.append(title, message);
  if (err.details && err.details.length) {
    const list = document.createElement("ul");
    for (const d of err.details) {
      const item = document.createElement("li");
      item.className = "error-detail";
      item.dataset.field = d.field;
      const field = document.createElement("code");
      field.textContent = d.field || "(body)";
      item.append(field, document.createTextNode(` ${d.message}`));
      list.appendChild(item);
    }
    box.appendChild(list);
  }
  if (err.status === 401 || err.status === 403) {
    const hint = document.createElement("div");
    hint.className = "note";
    hint.textContent = "The service asks for an API key: enter it in the key field above and load again.";
    box.appendChild(hint);
    $("api-key").focus();
  }
  box.hidden = false;
  body.dataset.planStatus = "error";
  body.dataset.planError = code;
  setBadge("error", "error");
}

function facts(pairs) {
  const dl = document.createElement("dl");
  dl.className = "facts";
  for (const [k, v] of pairs) {
    if (v === undefined || v === null || v === "") continue;
    const dt = document.createElement("dt");
    dt.textContent = k;
    const dd = document.createElement("dd");
    dd.textContent = v;
    dl.append(dt, dd);
  }
  return dl;
}

function setSummary(status, message, pairs, notes = []) {
  const box = $("summary");
  box.replaceChildren();
  if (status) {
    const line = document.createElement("div");
    line.className = "status-line";
    line.textContent = status;
    box.appendChild(line);
  }
  if (message) {
    const m = document.createElement("div");
    m.className = "message";
    m.id = "plan-message";
    m.textContent = message;
    box.appendChild(m);
  }
  box.appendChild(facts(pairs));
  for (const text of notes) addNote(text);
}

function addNote(text) {
  const n = document.createElement("div");
  n.className = "note";
  n.textContent = text;
  $("summary").appendChild(n);
}

/** The lane decision in words (diagnostics.decision: keep or borrow the road, and why), if there is one. */
function laneDecision(diagnostics) {
  const decision = diagnostics && diagnostics.decision;
  if (!decision || typeof decision.lane !== "string") return undefined;
  const why = decision.reason && typeof decision.reason.message === "string" ? decision.reason.message : "";
  return why ? `${decision.lane}: ${why}` : decision.lane;
}

function setDiagnostics(value) {
  const box = $("diagnostics-body");
  box.replaceChildren();
  if (value !== undefined && value !== null) box.appendChild(tree(value));
}

// ------------------------------------------------------------------------------------------------
// Colours and legend
// ------------------------------------------------------------------------------------------------

const VIRIDIS = ["#440154", "#414487", "#2a788e", "#22a884", "#7ad151", "#fde725"];

function speedColour(v) {
  const [lo, hi] = state.vScale;
  const f = Math.min(Math.max((v - lo) / (hi - lo || 1), 0), 1) * (VIRIDIS.length - 1);
  const i = Math.min(Math.floor(f), VIRIDIS.length - 2);
  const mix = (a, b, w) => Math.round(a + (b - a) * w);
  const rgb = (hex) => [1, 3, 5].map((k) => parseInt(hex.slice(k, k + 2), 16));
  const [a, b] = [rgb(VIRIDIS[i]), rgb(VIRIDIS[i + 1])];
  return `rgb(${mix(a[0], b[0], f - i)}, ${mix(a[1], b[1], f - i)}, ${mix(a[2], b[2], f - i)})`;
}

/** The legend of what the map holds now (state.legend's flags, the obstacles' kinds, the road). */
function legendEntries() {
  const has = state.legend || {};
  const kinds = new Set(state.obstacleNodes.map((o) => o.kind));
  const folds = Number($("map").dataset.foldsAlg4 || 0) > 0;
  return [
    state.trajectory && ["gradient"],
    has.driven && ["swatch", "#6a3d9a", "driven path"],
    has.candidates && ["swatch", "#4c78a8", has.repaired ? "candidates (dashed: repaired by TransF-κ)" : "candidates"],
    has.chosen && ["swatch", "#0b3d91", "chosen candidate"],
    folds && ["swatch", "#f58518", "candidates Algorithm 4 would fold"],
    folds && !has.driven && ["swatch dashed", "#d62728", "… as Algorithm 4 draws them"],
    (kinds.has("polygon") || kinds.has("circle")) && ["box", "#e4572e", "static obstacle"],
    kinds.has("dynamic") && ["box", "#f0a202", "moving obstacle, at t"],
    state.road && state.road.roadLeft && ["swatch", "#5c6675", "road edge"],
    state.trajectory && ["box", "#2a9d8f", "vehicle, at t"],
  ].filter(Boolean);
}

function setLegend(entries) {
  const box = $("legend");
  box.replaceChildren();
  for (const [kind, colour, label] of entries) {
    const mark = document.createElement("span");
    if (kind === "gradient") {
      mark.className = "gradient";
      mark.style.background = `linear-gradient(to right, ${VIRIDIS.join(", ")})`;
      const text = document.createElement("span");
      text.className = "scale";
      const [lo, hi] = state.vScale;
      text.textContent = `speed ${num(lo, 1)} – ${num(hi, 1)} m/s`;
      const row = document.createElement("div");
      row.className = "gradient-row";
      row.append(mark, text);
      box.append(row);
      continue;
    }
    mark.className = kind;
    if (kind === "box") {
      mark.style.borderColor = colour;
      mark.style.background = `${colour}88`;
    } else {
      mark.style.borderTopColor = colour;
    }
    const text = document.createElement("span");
    text.textContent = label;
    box.append(mark, text);
  }
}

// ------------------------------------------------------------------------------------------------
// Drawing the request: road, lane, reference, obstacles
// ------------------------------------------------------------------------------------------------

function vehicleOf(request) {
  return { ...defaults, ...(request && typeof request.vehicle === "object" ? request.vehicle : {}) };
}

function drawRoad(request, { lane: withLane = true } = {}) {
  map.clear("road", "lane", "reference");
  const curve = referenceCurve(request.reference_line);
  const lane = request.lane && typeof request.lane === "object" ? request.lane : {};
  const left = widthsAlong(lane.left_width ?? 0, curve, "lane.left_width");
  const right = widthsAlong(lane.right_width ?? 0, curve, "lane.right_width");
  const road = { curve, left, right, roadLeft: null, roadRight: null, outline: [] };
  const quadsPath = (quads) => quads.map((q) => pathData(q, true)).join("");
  if (request.road && typeof request.road === "object") {
    road.roadLeft = widthsAlong(request.road.left_width ?? 0, curve, "road.left_width");
    road.roadRight = widthsAlong(request.road.right_width ?? 0, curve, "road.right_width");
    const lower = road.roadRight.map((w) => -w);
    el("path", { class: "road-area", d: quadsPath(bandQuads(curve, lower, road.roadLeft)) }, map.layers.road);
    for (const edge of [...offsetCurve(curve, road.roadLeft), ...offsetCurve(curve, lower)]) {
      el("path", { class: "road-edge", d: pathData(edge) }, map.layers.road);
      road.outline.push(...edge);
    }
  }
  const lower = right.map((w) => -w);
  if (withLane) {
    el("path", { class: "lane-area", d: quadsPath(bandQuads(curve, lower, left)) }, map.layers.lane);
    for (const edge of [...offsetCurve(curve, left), ...offsetCurve(curve, lower)]) {
      el("path", { class: "lane-edge", d: pathData(edge) }, map.layers.lane);
      road.outline.push(...edge);
    }
  }
  const centre = curve.x.map((x, i) => [x, curve.y[i]]);
  el("path", { class: "reference", d: pathData(centre) }, map.layers.reference);
  road.outline.push(...centre);
  return road;
}

function drawObstacles(obstacles) {
  map.clear("obstacles", "predictions", "labels");
  state.obstacleNodes = [];
  const points = [];
  (Array.isArray(obstacles) ? obstacles : []).forEach((ob, i) => {
    const kind = obstacleKind(ob);
    const id = ob && ob.id !== undefined ? String(ob.id) : `#${i}`;
    let node = null;
    let at = null;
    if (kind === "polygon" && Array.isArray(ob.polygon)) {
      node = el("polygon", { class: "obstacle static", points: ob.polygon.map(([x, y]) => `${x},${-y}`).join(" ") });
      points.push(...ob.polygon);
      at = ob.polygon[0];
    } else if (kind === "circle" && ob.circle && Array.isArray(ob.circle.center)) {
      const [cx, cy] = ob.circle.center;
      node = el("circle", { class: "obstacle static", cx, cy: -cy, r: ob.circle.radius });
      points.push([cx - ob.circle.radius, cy - ob.circle.radius], [cx + ob.circle.radius, cy + ob.circle.radius]);
      at = [cx, cy + ob.circle.radius];
    } else if (kind === "dynamic" && Array.isArray(ob.prediction) && ob.prediction.length) {
      const track = ob.prediction.map((p) => [p.x, p.y]);
      el("path", { class: "prediction", d: pathData(track), "data-id": id }, map.layers.predictions);
      node = el("polygon", { class: "obstacle moving" });
      points.push(...track);
    }
    if (!node) return;
    node.dataset.id = id;
    node.dataset.index = String(i);
    node.dataset.kind = kind;
    const title = el("title", {}, node);
    title.textContent = `${id} (${kind})`;
    map.layers.obstacles.appendChild(node);
    const label = el("text", { class: "label" }, map.layers.labels);
    label.textContent = id;
    state.obstacleNodes.push({ ob, kind, node, label, at });
  });
  $("map").dataset.obstacles = String(state.obstacleNodes.length);
  updateObstacles(0);
  return points;
}

/** The box grown to at least `half` metres either side of its centre (null stays null). */
function atLeast(box, half) {
  if (!box) return null;
  const cx = (box.minX + box.maxX) / 2;
  const cy = (box.minY + box.maxY) / 2;
  const hx = Math.max((box.maxX - box.minX) / 2, half);
  const hy = Math.max((box.maxY - box.minY) / 2, half);
  return { minX: cx - hx, maxX: cx + hx, minY: cy - hy, maxY: cy + hy };
}

function placeLabel(label, x, y) {
  label.setAttribute("x", x);
  label.setAttribute("y", -y);
}

/** Moving obstacles at time t [s] (the request's predictions; a run's are on the sim's clock). */
function updateObstacles(t) {
  for (const { ob, kind, node, label, at } of state.obstacleNodes) {
    if (kind === "dynamic") {
      const p = predictionAt(ob.prediction, t);
      const corners = boxCorners(p.x, p.y, p.heading, ob.length, ob.width);
      node.setAttribute("points", corners.map(([x, y]) => `${x},${-y}`).join(" "));
      placeLabel(label, p.x, p.y + ob.width / 2 + 0.6);
    } else if (at) {
      placeLabel(label, at[0], at[1] + 0.6);
    }
  }
}

// ------------------------------------------------------------------------------------------------
// Drawing a plan: candidates, trajectory by speed, footprints, ego
// ------------------------------------------------------------------------------------------------

function drawCandidates(list) {
  map.clear("candidates", "ghosts");
  list.forEach((c, i) => {
    if (c.points.length < 2) return;
    el("path", {
      class: "candidate",
      d: pathData(c.points),
      "data-index": i,
      "data-repaired": c.repaired ? "true" : "false",
      "data-folds-alg4": c.folds === undefined ? "unknown" : String(Boolean(c.folds)),
      "data-chosen": c.chosen ? "true" : null,
    }, map.layers.candidates);
  });
  $("map").dataset.candidates = String(list.length);
}

function markCandidateFolds(folds, ghosts = []) {
  for (const path of map.layers.candidates.querySelectorAll(".candidate")) {
    path.dataset.foldsAlg4 = String(folds.has(Number(path.dataset.index)));
  }
  map.clear("ghosts");
  for (const points of ghosts) el("path", { class: "ghost", d: pathData(points) }, map.layers.ghosts);
  $("map").dataset.foldsAlg4 = String(folds.size);
}

function columns(points) {
  const out = { t: [], x: [], y: [], heading: [], curvature: [], v: [], a: [], s: [], d: [] };
  for (const p of points) for (const k of Object.keys(out)) out[k].push(Number(p[k]));
  return out;
}

function drawTrajectory(traj, vehicle) {
  map.clear("trajectory", "footprints");
  const n = traj.t.length;
  const pts = traj.x.map((x, i) => [x, traj.y[i]]);
  const layer = map.layers.trajectory;
  el("path", { class: "trajectory-halo", d: pathData(pts) }, layer);
  for (let i = 0; i + 1 < n; i++) {
    el("line", {
      class: "trajectory-segment",
      x1: pts[i][0], y1: -pts[i][1], x2: pts[i + 1][0], y2: -pts[i + 1][1],
      stroke: speedColour(0.5 * (traj.v[i] + traj.v[i + 1])),
    }, layer);
  }
  if (n === 1) el("circle", { class: "ego-nose", cx: pts[0][0], cy: -pts[0][1], r: 0.3 }, layer);
  // a footprint every second of the plan (and the last)
  const dt = n > 1 ? traj.t[1] - traj.t[0] : 1;
  const every = Math.max(1, Math.round(1 / (dt || 1)));
  for (let i = 0; i < n; i += every) footprint(traj, i, vehicle);
  if ((n - 1) % every) footprint(traj, n - 1, vehicle);
  $("map").dataset.trajectoryPoints = String(n);
  return pts;
}

function footprint(traj, i, vehicle) {
  const corners = boxCorners(traj.x[i], traj.y[i], traj.heading[i], vehicle.length, vehicle.width);
  el("path", { class: "footprint", d: pathData(corners, true) }, map.layers.footprints);
}

function drawEgo(pose, vehicle) {
  map.clear("ego");
  if (!pose) return;
  const corners = boxCorners(pose.x, pose.y, pose.heading, vehicle.length, vehicle.width);
  el("path", { class: "ego", d: pathData(corners, true) }, map.layers.ego);
  const c = Math.cos(pose.heading);
  const s = Math.sin(pose.heading);
  const tip = [pose.x + c * vehicle.length * 0.5, pose.y + s * vehicle.length * 0.5];
  const back = vehicle.length * 0.22;
  const side = vehicle.width * 0.3;
  const nose = [
    tip,
    [tip[0] - c * back - s * side, tip[1] - s * back + c * side],
    [tip[0] - c * back + s * side, tip[1] - s * back - c * side],
  ];
  el("path", { class: "ego-nose", d: pathData(nose, true) }, map.layers.ego);
}

/** d(s) and κ(s) of the road along [s0, s1] for the plots. */
function roadSeries(road, s0, s1) {
  const out = { s: [], kappa: [], left: [], right: [], roadLeft: [], roadRight: [] };
  if (!road) return out;
  const c = road.curve;
  for (let i = 0; i < c.s.length; i++) {
    if (c.s[i] < s0 || c.s[i] > s1) continue;
    out.s.push(c.s[i]);
    out.kappa.push(c.kappa[i]);
    out.left.push(road.left[i]);
    out.right.push(-road.right[i]);
    if (road.roadLeft) {
      out.roadLeft.push(road.roadLeft[i]);
      out.roadRight.push(-road.roadRight[i]);
    }
  }
  return out;
}

function limitSeries(x0, x1, values) {
  if (!(x1 > x0)) return [];
  return values.filter((v) => Number.isFinite(v)).map((v) => ({ x: [x0, x1], y: [v, v], cls: "limit" }));
}

function setPlots({ traj, tOffset = 0, history = null, candidates = [], request, tRange = null }) {
  const vehicle = vehicleOf(request);
  const ts = traj ? traj.t.map((t) => t + tOffset) : [];
  // without a trajectory the limits alone would draw empty charts: "no data" instead
  const t0 = tRange ? tRange[0] : ts[0] ?? 0;
  const t1 = tRange ? tRange[1] : ts[ts.length - 1] ?? 0;
  let s0 = Infinity;
  let s1 = -Infinity;
  for (const list of [traj ? traj.s : [], history ? history.s : [], ...candidates.map((c) => c.s)]) {
    for (const s of list) {
      if (!Number.isFinite(s)) continue;
      s0 = Math.min(s0, s);
      s1 = Math.max(s1, s);
    }
  }
  // nothing planned: the road's κ(s) and widths along the whole reference
  if (!(s1 >= s0)) [s0, s1] = [0, state.road ? state.road.curve.length : 0];
  const rs = roadSeries(state.road, s0, s1);
  const target = request && request.options ? request.options.target_speed : null;
  plots.v.setData([
    history && { x: history.t, y: history.v, cls: "history" },
    traj && { x: ts, y: traj.v, cls: "main" },
    ...limitSeries(t0, t1, [vehicle.max_speed, target ?? NaN]),
  ]);
  plots.a.setData([
    traj && { x: ts, y: traj.a, cls: "main" },
    ...limitSeries(t0, t1, [vehicle.max_acceleration, -vehicle.max_deceleration]),
  ]);
  plots.kappa.setData([
    { x: rs.s, y: rs.kappa, cls: "reference" },
    traj && { x: traj.s, y: traj.curvature, cls: "main" },
    ...limitSeries(s0, s1, [vehicle.max_curvature, -vehicle.max_curvature]),
  ]);
  plots.d.setData([
    { x: rs.s, y: rs.left, cls: "bound" },
    { x: rs.s, y: rs.right, cls: "bound" },
    rs.roadLeft.length && { x: rs.s, y: rs.roadLeft, cls: "bound" },
    rs.roadRight.length && { x: rs.s, y: rs.roadRight, cls: "bound" },
    ...candidates.map((c) => ({ x: c.s, y: c.d, cls: "faint" })),
    history && { x: history.s, y: history.d, cls: "history" },
    traj && { x: traj.s, y: traj.d, cls: "main" },
  ]);
}

// ------------------------------------------------------------------------------------------------
// Time
// ------------------------------------------------------------------------------------------------

function setTimeRange(tMax, step) {
  state.tMax = Math.max(tMax, 0);
  const slider = $("time");
  slider.max = String(state.tMax);
  slider.step = String(step || 0.01);
}

function setTime(t) {
  state.t = Math.min(Math.max(t, 0), state.tMax);
  $("time").value = String(state.t);
  $("map").dataset.time = state.t.toFixed(3);
  if (state.view === "plan") showPlanTime();
  else if (state.view === "run") showRunTime();
}

function showPlanTime() {
  const traj = state.trajectory;
  updateObstacles(state.t);
  if (!traj) {
    $("time-label").textContent = `t = ${state.t.toFixed(2)} s`;
    return;
  }
  const pose = trajectoryAt(traj, state.t);
  drawEgo(pose, vehicleOf(state.request));
  plots.v.setCursor(state.t);
  plots.a.setCursor(state.t);
  plots.kappa.setCursor(pose.s);
  plots.d.setCursor(pose.s);
  $("time-label").textContent = `t = ${state.t.toFixed(2)} s · v = ${pose.v.toFixed(2)} m/s · s = ${pose.s.toFixed(1)} m`;
}

function setPlaying(on) {
  state.playing = on && state.tMax > 0;
  $("play").textContent = state.playing ? "❚❚" : "▶";
  $("play").setAttribute("aria-label", state.playing ? "Pause" : "Play");
  if (!state.playing) return;
  if (state.t >= state.tMax) setTime(0);
  let last = performance.now();
  const tick = (now) => {
    if (!state.playing) return;
    const speed = Number($("speed").value) || 1;
    const t = state.t + ((now - last) / 1000) * speed;
    last = now;
    setTime(t);
    if (state.t >= state.tMax) {
      setPlaying(false);
      return;
    }
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
}

// ------------------------------------------------------------------------------------------------
// Plans
// ------------------------------------------------------------------------------------------------

function withOptions(request, options) {
  return { ...request, options: { ...(request.options && typeof request.options === "object" ? request.options : {}), ...options } };
}

function guarded(what, draw) {
  try {
    return draw();
  } catch (exc) {
    addNote(`Not drawn: ${what} (${exc.message})`);
    return null;
  }
}

async function showPlan(request, token, signal) {
  state.view = "plan";
  body.dataset.view = "plan";
  state.request = request;
  map.clear();
  setSummary("planning…", "", []);
  setDiagnostics(null);
  const points = [];
  state.road = guarded("the road", () => drawRoad(request));
  if (state.road) points.push(...state.road.outline);
  points.push(...(guarded("the obstacles", () => drawObstacles(request.obstacles)) || []));
  guarded("the goal", () => drawGoal(requestGoal(request.goal)));
  map.extent = bounds(points);
  map.fit(map.extent);
  setBadge("planning…", "busy");
  const asked = withOptions(request, { return_candidates: true });
  let answer;
  try {
    answer = await post("v1/plan", asked, signal);
  } catch (exc) {
    if (exc.name === "AbortError" || token !== state.token) return;
    setSummary("not planned", "", [["request", describeRequest(request)]]);
    showError(exc, "POST /v1/plan");
    setPlots({ traj: null, request });
    return;
  }
  if (token !== state.token) return;
  drawAnswer(request, answer);
  markFolds(request, answer, token, signal);
}

function describeRequest(request) {
  const n = Array.isArray(request.obstacles) ? request.obstacles.length : 0;
  const gen = request.options && request.options.generator ? request.options.generator : "transf_kappa";
  return `${n} obstacle${n === 1 ? "" : "s"}, generator ${gen}`;
}

function drawAnswer(request, answer) {
  state.answer = answer;
  const vehicle = vehicleOf(request);
  const traj = columns(Array.isArray(answer.trajectory) ? answer.trajectory : []);
  state.trajectory = traj.t.length ? traj : null;
  const vs = traj.v.filter(Number.isFinite);
  state.vScale = [Math.min(0, ...vs), Math.max(1, ...vs)];
  const cands = (answer.candidates || []).map((c) => ({
    points: c.points.map((p) => [p.x, p.y]),
    s: c.points.map((p) => p.s),
    d: c.points.map((p) => p.d),
    repaired: c.repaired,
  }));
  drawCandidates(cands);
  const pts = state.trajectory ? drawTrajectory(traj, vehicle) : [];
  // home: the plan and its candidates (a long road would make them specks); "all": the road too
  map.extent = bounds(pts, ...(state.road ? [state.road.outline] : []), ...cands.map((c) => c.points));
  map.fit(atLeast(bounds(pts, ...cands.map((c) => c.points)), 20) || map.extent);
  setPlots({ traj: state.trajectory, candidates: cands, request });
  const status = String(answer.status);
  body.dataset.planStatus = status;
  setBadge(status, status === "ok" || status === "stopped" || status === "fallback" ? status : "error");
  const repaired = cands.filter((c) => c.repaired).length;
  setSummary(`status: ${status}`, answer.message, [
    ["lane", laneDecision(answer.diagnostics)],
    ["trajectory", `${traj.t.length} points over ${num(traj.t[traj.t.length - 1] ?? 0, 2)} s`],
    ["candidates", `${cands.length} (${repaired} repaired by TransF-κ)`],
    ["obstacles", String(state.obstacleNodes.length)],
    ["request", describeRequest(request)],
  ]);
  setDiagnostics(answer.diagnostics);
  state.legend = { candidates: cands.length > 0, repaired: repaired > 0 };
  setLegend(legendEntries());
  const dt = traj.t.length > 1 ? traj.t[1] - traj.t[0] : 0.01;
  setTimeRange(traj.t[traj.t.length - 1] ?? 0, Math.min(dt / 4, 0.05));
  setTime(0);
}

/** Mark the candidates whose Algorithm 4 version folds: the naive candidates of the same request
 * and seed (POST /v1/candidates with generator naive; the plan's own when it used naive), their
 * TransF-κ arc lengths (POST /v1/frenet), and the planner's fold test on them: s not strictly
 * increasing, or the polyline crossing itself. */
async function markFolds(request, answer, token, signal) {
  const cands = answer.candidates || [];
  if (!cands.length) {
    body.dataset.folds = "none";
    markCandidateFolds(new Set());
    return;
  }
  try {
    const generator = request.options && request.options.generator;
    const naive = generator === "naive"
      ? cands
      : (await post("v1/candidates", withOptions(request, { generator: "naive", return_candidates: false }), signal)).candidates;
    if (token !== state.token) return;
    const paths = naive.map((c) => c.points.map((p) => [p.x, p.y]));
    const total = paths.reduce((n, p) => n + p.length, 0);
    if (total > MAX_FOLD_POINTS) {
      body.dataset.folds = "skipped";
      addNote(`Algorithm 4 folds not marked: ${total} candidate points (at most ${MAX_FOLD_POINTS} are tested).`);
      return;
    }
    const flat = paths.flat();
    const s = [];
    for (let i = 0; i < flat.length; i += frenetLimit) {
      const part = await post("v1/frenet", { reference_line: request.reference_line, points: flat.slice(i, i + frenetLimit) }, signal);
      s.push(...part.s);
    }
    if (token !== state.token) return;
    const folds = new Set();
    const ghosts = [];
    let at = 0;
    paths.forEach((p, i) => {
      if (foldsBack(p, s.slice(at, at + p.length))) {
        folds.add(i);
        ghosts.push(p);
      }
      at += p.length;
    });
    markCandidateFolds(folds, generator === "naive" ? [] : ghosts);
    setLegend(legendEntries());
    body.dataset.folds = "marked";
    addNote(`${folds.size} of ${cands.length} candidates fold back as Algorithm 4 draws them (orange; their naive version red dashed).`);
  } catch (exc) {
    if (exc.name === "AbortError" || token !== state.token) return;
    body.dataset.folds = "unavailable";
    addNote(`Algorithm 4 folds not marked: ${exc.code || "error"}: ${exc.message}`);
  }
}

// ------------------------------------------------------------------------------------------------
// Coordinate conversions (/v1/frenet, /v1/cartesian examples)
// ------------------------------------------------------------------------------------------------

async function showConversion(kind, request, token, signal) {
  state.view = kind;
  body.dataset.view = kind;
  state.request = request;
  state.trajectory = null;
  map.clear();
  setPlots({ traj: null, request: null });
  setDiagnostics(null);
  state.legend = {};
  setLegend([]);
  setTimeRange(0, 0.01);
  $("plots").hidden = true;
  state.road = guarded("the reference line", () => drawRoad({ reference_line: request.reference_line }, { lane: false }));
  const outline = state.road ? state.road.outline : [];
  map.extent = bounds(outline);
  map.fit(map.extent);
  setBadge("converting…", "busy");
  const path = kind === "frenet" ? "v1/frenet" : "v1/cartesian";
  let xy;
  let sd;
  try {
    if (kind === "frenet") {
      const answer = await post(path, request, signal);
      xy = request.points;
      sd = answer.s.map((s, i) => [s, answer.d[i]]);
    } else {
      sd = request.frenet;
      xy = (await post(path, request, signal)).points;
    }
    // the foot of each point on the reference: (s, 0) to Cartesian
    const feet = (await post("v1/cartesian", { reference_line: request.reference_line, frenet: sd.map(([s]) => [s, 0]) }, signal)).points;
    if (token !== state.token) return;
    xy.forEach(([x, y], i) => {
      el("path", { class: "query-foot", d: pathData([feet[i], [x, y]]) }, map.layers.points);
      el("circle", { class: "query-point", cx: x, cy: -y, r: 0.35, "data-index": i }, map.layers.points);
      const label = el("text", { class: "label", x, y: -y - 0.8 }, map.layers.labels);
      label.textContent = `s ${sd[i][0].toFixed(2)}, d ${sd[i][1].toFixed(2)}`;
    });
    $("map").dataset.points = String(xy.length);
    map.extent = bounds(outline, xy, feet);
    map.fit(map.extent);
    body.dataset.planStatus = "ok";
    setBadge("converted", "ok");
    setSummary(`POST /${path}`, `${xy.length} point${xy.length === 1 ? "" : "s"} converted`, [
      ["reference", `${request.reference_line.length} points`],
    ]);
    setDiagnostics({ points: xy.map(([x, y], i) => ({ x, y, s: sd[i][0], d: sd[i][1] })) });
  } catch (exc) {
    if (exc.name === "AbortError" || token !== state.token) return;
    setSummary("not converted", "", []);
    showError(exc, `POST /${path}`);
  }
}

// ------------------------------------------------------------------------------------------------
// Runs (decoded by runfile.js)
// ------------------------------------------------------------------------------------------------

function showRun(doc) {
  const run = decodeRun(doc);
  state.view = "run";
  body.dataset.view = "run";
  state.run = run;
  state.request = doc.request;
  state.answer = null;
  map.clear();
  const points = [];
  state.road = guarded("the road", () => drawRoad(doc.request));
  if (state.road) points.push(...state.road.outline);
  points.push(...(guarded("the obstacles", () => drawObstacles(doc.request.obstacles)) || []));
  guarded("the goal", () => drawGoal(doc.goal));
  points.push(...run.driven.xy);
  const vs = [...run.driven.v];
  run.cycles.forEach((_, k) => {
    const c = cycleData(run, k);
    if (c.traj) vs.push(...c.traj.v);
  });
  state.vScale = [0, Math.max(1, ...vs.filter(Number.isFinite))];
  map.extent = bounds(points);
  const planned = run.cycles.map((_, k) => cycleData(run, k).traj).filter(Boolean);
  map.fit(atLeast(bounds(run.driven.xy, ...planned.map((tr) => tr.x.map((x, i) => [x, tr.y[i]]))), 20) || map.extent);
  body.dataset.runCycles = String(run.cycles.length);
  run.lastCycle = -1;
  state.legend = { candidates: true, driven: true, chosen: true };
  setLegend(legendEntries());
  $("run-steps").hidden = false;
  const tEnd = run.driven.t[run.driven.t.length - 1] ?? 0;
  setTimeRange(tEnd, Math.min(doc.replan_period / 4, 0.05));
  setTime(0);
}

/** A request's `goal.position` (polygon or circle) in drawGoal's terms; null without one. */
function requestGoal(goal) {
  const position = goal && goal.position;
  if (!position) return null;
  if (Array.isArray(position.polygon)) return { polygon: position.polygon };
  const circle = position.circle;
  if (circle && Array.isArray(circle.center)) return { position: circle.center, radius: circle.radius };
  return null;
}

function drawGoal(goal) {
  map.clear("goal");
  if (!goal) return;
  if (Array.isArray(goal.polygon)) {
    el("path", { class: "goal", d: pathData(goal.polygon, true) }, map.layers.goal);
  }
  if (Array.isArray(goal.position) && Number.isFinite(goal.radius)) {
    el("circle", { class: "goal", cx: goal.position[0], cy: -goal.position[1], r: goal.radius }, map.layers.goal);
  }
  if (Number.isFinite(goal.s_min) && state.road) {
    const c = curveAt(state.road.curve, goal.s_min);
    const l = interp(goal.s_min, state.road.curve.s, state.road.left);
    const r = interp(goal.s_min, state.road.curve.s, state.road.right);
    el("path", { class: "goal", d: pathData([[c.x - c.nx * r, c.y - c.ny * r], [c.x + c.nx * l, c.y + c.ny * l]]) }, map.layers.goal);
  }
}

function showRunTime() {
  const run = state.run;
  if (!run || !run.cycles.length) return;
  const t = state.t;
  const k = cycleAt(run, t);
  const c = cycleData(run, k);
  const vehicle = vehicleOf(state.request);
  if (k !== run.lastCycle) {
    run.lastCycle = k;
    drawCandidates(c.candidates);
    markCandidateFolds(c.alg4);
    state.trajectory = c.traj;
    if (c.traj) drawTrajectory(c.traj, vehicle);
    else map.clear("trajectory", "footprints");
    setLegend(legendEntries());
    body.dataset.cycle = String(k);
    body.dataset.planStatus = c.status;
    body.dataset.folds = "marked";
    setBadge(c.status, c.status === "error" ? "error" : c.status);
    const doc = run.doc;
    setSummary(`cycle ${k + 1} of ${run.cycles.length} · ${c.status}`, c.message, [
      ["cycle t", `${num(c.t, 2)} s`],
      ["planning", `${num(c.planning_ms, 1)} ms`],
      ["candidates", `${c.candidates.length} (${c.alg4.size} Algorithm 4 would fold${c.folded && c.folded.length ? `, ${c.folded.length} fold as planned` : ""})`],
      ["chosen", c.chosen === null || c.chosen === undefined ? "—" : String(c.chosen)],
      ["run", `${doc.generator}, ${doc.termination} after ${num(run.driven.t[run.driven.t.length - 1] ?? 0, 1)} s`],
    ]);
    setDiagnostics({
      cycle: { t: c.t, status: c.status, message: c.message, planning_ms: c.planning_ms, chosen: c.chosen, state: c.state, folded: c.folded, alg4_folds: c.alg4_folds },
      run: { source: doc.source, generator: doc.generator, replan_period: doc.replan_period, termination: doc.termination, goal: doc.goal, metrics: doc.metrics },
    });
    const upto = run.driven.t.findIndex((tt) => tt > c.t + 1e-9);
    const n = upto < 0 ? run.driven.t.length : upto;
    setPlots({
      traj: c.traj,
      tOffset: c.t,
      history: { t: run.driven.t.slice(0, n), v: run.driven.v.slice(0, n), s: run.driven.s.slice(0, n), d: run.driven.d.slice(0, n) },
      request: state.request,
      tRange: [0, state.tMax],
    });
  }
  // the driven path up to t, the vehicle at t
  map.clear("driven");
  const d = run.driven;
  const upto = d.t.findIndex((tt) => tt > t + 1e-9);
  const n = upto < 0 ? d.t.length : upto;
  el("path", { class: "driven ahead", d: pathData(d.xy) }, map.layers.driven);
  if (n > 1) el("path", { class: "driven", d: pathData(d.xy.slice(0, n)) }, map.layers.driven);
  const i = Math.max(n - 1, 0);
  const pose = { x: d.xy[i][0], y: d.xy[i][1], heading: d.yaw[i] };
  drawEgo(pose, vehicle);
  updateObstacles(t);
  plots.v.setCursor(t);
  plots.a.setCursor(t);
  const sNow = d.s.length ? d.s[i] : null;
  plots.kappa.setCursor(sNow);
  plots.d.setCursor(sNow);
  $("time-label").textContent = `t = ${t.toFixed(2)} s · cycle ${k + 1}/${run.cycles.length} · v = ${d.v[i].toFixed(2)} m/s`;
}

function stepCycle(delta) {
  const run = state.run;
  if (state.view === "run" && run) {
    const k = Math.min(Math.max(cycleAt(run, state.t) + delta, 0), run.cycles.length - 1);
    setTime(run.cycles[k].raw.t);
  } else if (state.trajectory) {
    const tr = state.trajectory.t;
    setTime(state.t + delta * (tr.length > 1 ? tr[1] - tr[0] : 0.1));
  }
}

// ------------------------------------------------------------------------------------------------
// Loading
// ------------------------------------------------------------------------------------------------

/** What a document is: "run", "plan", "frenet", "cartesian" or null. */
function kindOf(doc) {
  if (!doc || typeof doc !== "object" || Array.isArray(doc)) return null;
  if (doc.format === RUN_FORMAT) return "run";
  if ("points" in doc && "reference_line" in doc && !("lane" in doc)) return "frenet";
  if ("frenet" in doc && "reference_line" in doc && !("lane" in doc)) return "cartesian";
  if ("reference_line" in doc || "lane" in doc || "ego" in doc) return "plan";
  return null;
}

function begin() {
  if (state.controller) state.controller.abort();
  state.controller = new AbortController();
  state.token += 1;
  setPlaying(false);
  resetStatus();
  state.run = null;
  state.answer = null;
  state.trajectory = null;
  $("run-steps").hidden = true;
  $("plots").hidden = false;
  state.legend = {};
  setLegend([]);
  const mapData = $("map").dataset;
  for (const key of ["candidates", "foldsAlg4", "trajectoryPoints", "obstacles", "points"]) delete mapData[key];
  return { token: state.token, signal: state.controller.signal };
}

async function showDocument(doc, where) {
  const { token, signal } = begin();
  const kind = kindOf(doc);
  if (kind !== "run") $("request-text").value = JSON.stringify(doc, null, 2);
  try {
    if (kind === "run") showRun(doc);
    else if (kind === "plan") await showPlan(doc, token, signal);
    else if (kind === "frenet" || kind === "cartesian") await showConversion(kind, doc, token, signal);
    else {
      throw new ApiError({
        code: "unknown_document",
        message: `${where} is neither a planning request (reference_line, lane, ego, …), a /v1/frenet or /v1/cartesian body, nor a run file (format "${RUN_FORMAT}")`,
      });
    }
  } catch (exc) {
    if (exc.name === "AbortError" || token !== state.token) return;
    showError(exc, `Loading ${where}`);
  }
}

async function load(what, fetcher) {
  const { token, signal } = begin();
  setBadge("loading…", "busy");
  let doc;
  try {
    doc = await fetcher(signal);
  } catch (exc) {
    if (exc.name === "AbortError" || token !== state.token) return;
    showError(exc, `Loading ${what}`);
    return;
  }
  if (token === state.token) await showDocument(doc, what);
}

function loadDemo() {
  return load("the demo (GET /v1/demo)", (signal) => getJson("v1/demo", signal));
}

function loadUrl(url, what) {
  return load(`${what} ${url}`, (signal) => getJson(url, signal));
}

async function loadFile(file) {
  return load(file.name, async () => parseDocument(await file.arrayBuffer(), file.name));
}

function loadText() {
  return load("the pasted JSON", async () => parseJson($("request-text").value, "the pasted text"));
}

/** The request examples of the OpenAPI document into the examples menu; the API's limits and the
 * vehicle's defaults from its schemas. Without the document (docs turned off), only the demo. */
async function loadExamples() {
  const select = $("examples");
  let spec;
  try {
    spec = await getJson("openapi.json");
  } catch {
    select.title = "The service does not serve its OpenAPI document; only the demo is offered.";
    body.dataset.examples = "0";
    return;
  }
  const schemas = (spec.components && spec.components.schemas) || {};
  const vprops = schemas.Vehicle && schemas.Vehicle.properties;
  if (vprops) for (const k of Object.keys(defaults)) if (vprops[k] && typeof vprops[k].default === "number") defaults[k] = vprops[k].default;
  const fr = schemas.FrenetRequest && schemas.FrenetRequest.properties && schemas.FrenetRequest.properties.points;
  if (fr && Number.isInteger(fr.maxItems)) frenetLimit = fr.maxItems;
  const examples = [];
  for (const [path, ops] of Object.entries(spec.paths || {})) {
    for (const [method, op] of Object.entries(ops)) {
      const content = op && op.requestBody && op.requestBody.content && op.requestBody.content["application/json"];
      if (!content) continue;
      for (const [name, ex] of Object.entries(content.examples || {})) {
        if (ex && "value" in ex) examples.push({ label: `${method.toUpperCase()} ${path} · ${ex.summary || name}`, value: ex.value });
      }
      if (content.example) examples.push({ label: `${method.toUpperCase()} ${path} · example`, value: content.example });
    }
  }
  state.examples = examples;
  examples.forEach((ex, i) => {
    const option = document.createElement("option");
    option.value = String(i);
    option.textContent = ex.label;
    select.appendChild(option);
  });
  select.dataset.count = String(examples.length);
  body.dataset.examples = String(examples.length);
}

// ------------------------------------------------------------------------------------------------
// Wiring
// ------------------------------------------------------------------------------------------------

function wire() {
  $("load-demo").addEventListener("click", loadDemo);
  $("examples").addEventListener("change", (e) => {
    const ex = state.examples && state.examples[Number(e.target.value)];
    if (e.target.value !== "" && ex) showDocument(structuredClone(ex.value), ex.label);
  });
  $("open-file").addEventListener("click", () => $("file-input").click());
  $("file-input").addEventListener("change", (e) => {
    const file = e.target.files && e.target.files[0];
    if (file) loadFile(file);
    e.target.value = "";
  });
  $("toggle-editor").addEventListener("click", () => {
    const editor = $("editor");
    editor.hidden = !editor.hidden;
    $("toggle-editor").setAttribute("aria-expanded", String(!editor.hidden));
    if (!editor.hidden) $("request-text").focus();
  });
  $("plan-text").addEventListener("click", loadText);
  $("request-text").addEventListener("keydown", (e) => {
    if (e.key === "Enter" && (e.ctrlKey || e.metaKey)) {
      e.preventDefault();
      loadText();
    }
  });
  $("api-key").addEventListener("input", (e) => setApiKey(e.target.value));
  // docs behind the key: try the examples again once a key is given
  $("api-key").addEventListener("change", () => {
    if (!state.examples) loadExamples();
  });
  $("time").addEventListener("input", (e) => {
    setPlaying(false);
    setTime(Number(e.target.value));
  });
  $("play").addEventListener("click", () => setPlaying(!state.playing));
  $("prev-cycle").addEventListener("click", () => stepCycle(-1));
  $("next-cycle").addEventListener("click", () => stepCycle(1));
  $("zoom-in").addEventListener("click", () => map.zoom(1.5));
  $("zoom-out").addEventListener("click", () => map.zoom(1 / 1.5));
  $("zoom-fit").addEventListener("click", () => map.fitHome());
  $("zoom-all").addEventListener("click", () => map.fit(map.extent, false));
  for (const box of document.querySelectorAll("#layers input[data-layer]")) {
    const layer = box.dataset.layer;
    const apply = () => map.setVisible(layer, box.checked);
    box.addEventListener("change", apply);
    apply();
  }
  // labels stay 12 px: their font size is in metres, set on their layer
  map.onZoom = (metresPerPixel) => {
    map.layers.labels.style.fontSize = `${12 * metresPerPixel}px`;
  };
  document.addEventListener("keydown", (e) => {
    const tag = e.target && e.target.tagName;
    if (tag === "TEXTAREA" || tag === "INPUT" || tag === "SELECT") return;
    if (e.key === " ") {
      e.preventDefault();
      setPlaying(!state.playing);
    } else if (e.key === "ArrowRight") stepCycle(1);
    else if (e.key === "ArrowLeft") stepCycle(-1);
    else if (e.key === "+" || e.key === "=") map.zoom(1.5);
    else if (e.key === "-") map.zoom(1 / 1.5);
    else if (e.key === "0") map.fitHome();
    else if (e.key === "a") map.fit(map.extent, false);
  });
  // drop a file anywhere
  let depth = 0;
  const zone = $("drop-zone");
  document.addEventListener("dragenter", (e) => {
    if (!e.dataTransfer || !Array.from(e.dataTransfer.types).includes("Files")) return;
    depth += 1;
    zone.hidden = false;
  });
  document.addEventListener("dragleave", () => {
    depth = Math.max(depth - 1, 0);
    if (!depth) zone.hidden = true;
  });
  document.addEventListener("dragover", (e) => e.preventDefault());
  document.addEventListener("drop", (e) => {
    e.preventDefault();
    depth = 0;
    zone.hidden = true;
    const file = e.dataTransfer && e.dataTransfer.files && e.dataTransfer.files[0];
    if (file) loadFile(file);
  });
  window.addEventListener("resize", () => {
    for (const p of Object.values(plots)) p.render();
  });
}

function start() {
  wire();
  loadExamples();
  const params = new URLSearchParams(window.location.search);
  if (params.get("run")) loadUrl(params.get("run"), "the run");
  else if (params.get("request")) loadUrl(params.get("request"), "the request");
  else if (params.has("demo")) loadDemo();
  else {
    setSummary("Nothing loaded yet", "Plan the demo, pick an example, open or drop a request or a run file, or paste JSON.", []);
    for (const p of Object.values(plots)) p.setData([]);
  }
}

start();
