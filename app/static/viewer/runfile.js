// A run file (planner_tools/runfile.py; its JSON Schema: run.schema.json beside this file) decoded
// for playback. Every numeric series is fixed point and delta coded; a cycle is decoded when first
// shown and kept.

import { ApiError } from "./api.js";
import { decodePoints, decodeSeries } from "./geometry.js";

export const RUN_FORMAT = "kappa-planner-run";

const series = (values, scale) => Array.from(decodeSeries(values, scale));

/** The run of a run file's data: {doc, scale, driven: {t, xy, yaw, v, s, d}, cycles}. */
export function decodeRun(doc) {
  if (doc.version !== 1) {
    throw new ApiError({ code: "unsupported_run", message: `run file version ${doc.version}; this viewer reads version 1` });
  }
  const sc = doc.scale;
  const d = doc.driven;
  const driven = {
    t: series(d.t, sc.t),
    xy: decodePoints(d.xy, sc.xy),
    yaw: series(d.yaw, sc.yaw),
    v: series(d.v, sc.v),
    s: d.s ? series(d.s, sc.s) : [],
    d: d.d ? series(d.d, sc.d) : [],
  };
  return { doc, scale: sc, driven, cycles: doc.cycles.map((c) => ({ raw: c, decoded: null })) };
}

/** Cycle k of a run: its fields, the trajectory's columns (t from 0 at the cycle's start), the
 * candidates' points with their marks, and the set of candidates Algorithm 4 folds (alg4). */
export function cycleData(run, k) {
  const entry = run.cycles[k];
  if (entry.decoded) return entry.decoded;
  const c = entry.raw;
  const sc = run.scale;
  let traj = null;
  if (c.trajectory) {
    const tr = c.trajectory;
    const xy = decodePoints(tr.xy, sc.xy);
    traj = { t: xy.map((_, i) => i * tr.dt), x: xy.map((p) => p[0]), y: xy.map((p) => p[1]) };
    for (const name of ["heading", "curvature", "v", "a", "s", "d"]) traj[name] = series(tr[name], sc[name]);
  }
  const folded = new Set(c.folded || []);
  const alg4 = new Set(c.alg4_folds || []);
  const candidates = (c.candidates || []).map((points, i) => ({
    points: decodePoints(points, sc.xy), folds: alg4.has(i), folded: folded.has(i), chosen: c.chosen === i,
  }));
  entry.decoded = { ...c, traj, candidates, alg4 };
  return entry.decoded;
}

/** The index of the cycle running at sim time t [s]: the last one that started by then. */
export function cycleAt(run, t) {
  let lo = 0;
  let hi = run.cycles.length - 1;
  while (lo < hi) {
    const mid = (lo + hi + 1) >> 1;
    if (run.cycles[mid].raw.t <= t + 1e-9) lo = mid;
    else hi = mid - 1;
  }
  return lo;
}
