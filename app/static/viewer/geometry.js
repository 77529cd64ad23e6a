// Geometry of the viewer, pure functions on plain arrays (no DOM): the planner's reference curve,
// lane and road edges, obstacle outlines at a time, vehicle footprints, the fold test of a path,
// the run file's series. Units: metres, seconds, radians; d is positive to the left.

/** Is every argument a finite number? */
export function finite(...values) {
  return values.every((v) => typeof v === "number" && Number.isFinite(v));
}

/** The polyline [[x, y], …] without consecutive duplicates (closer than 1e-6 m), as the planner
 * cleans it; also the index of each kept point in the input. Throws on a malformed polyline. */
export function cleanPolyline(points) {
  if (!Array.isArray(points)) throw new Error("reference_line is not a list");
  const xy = [];
  const index = [];
  points.forEach((p, i) => {
    if (!Array.isArray(p) || p.length !== 2 || !finite(p[0], p[1])) {
      throw new Error(`reference_line.${i} is not a finite [x, y] pair`);
    }
    const last = xy[xy.length - 1];
    if (!last || Math.hypot(p[0] - last[0], p[1] - last[1]) > 1e-6) {
      xy.push([p[0], p[1]]);
      index.push(i);
    }
  });
  if (xy.length < 2) throw new Error("reference_line needs two distinct points");
  return { xy, index };
}

/** Second derivatives of a not-a-knot cubic spline through values y at knots u (the planner fits
 * scipy's CubicSpline(bc_type="not-a-knot") by chord length). n ≥ 4; the not-a-knot conditions
 * are eliminated into the first and last rows, leaving a tridiagonal system (Thomas algorithm). */
function notAKnotMoments(u, y) {
  const n = u.length;
  const h = [];
  for (let i = 0; i < n - 1; i++) h.push(u[i + 1] - u[i]);
  const m = n - 2; // unknowns M1 … M(n-2)
  const a = new Float64Array(m);
  const b = new Float64Array(m);
  const c = new Float64Array(m);
  const r = new Float64Array(m);
  for (let k = 0; k < m; k++) {
    const i = k + 1;
    a[k] = h[i - 1];
    b[k] = 2 * (h[i - 1] + h[i]);
    c[k] = h[i];
    r[k] = 6 * ((y[i + 1] - y[i]) / h[i] - (y[i] - y[i - 1]) / h[i - 1]);
  }
  // M0 = ((h0 + h1) M1 − h0 M2) / h1 and M(n-1) likewise: substituted into the first and last rows
  const h0 = h[0];
  const h1 = h[1];
  b[0] += (a[0] * (h0 + h1)) / h1;
  c[0] -= (a[0] * h0) / h1;
  a[0] = 0;
  const hl = h[n - 2];
  const hk = h[n - 3];
  b[m - 1] += (c[m - 1] * (hl + hk)) / hk;
  a[m - 1] -= (c[m - 1] * hl) / hk;
  c[m - 1] = 0;
  for (let k = 1; k < m; k++) {
    const w = a[k] / b[k - 1];
    b[k] -= w * c[k - 1];
    r[k] -= w * r[k - 1];
  }
  const x = new Array(m);
  x[m - 1] = r[m - 1] / b[m - 1];
  for (let k = m - 2; k >= 0; k--) x[k] = (r[k] - c[k] * x[k + 1]) / b[k];
  return finishMoments(x, h);
}

function finishMoments(inner, h) {
  const n = inner.length + 2;
  const M = new Float64Array(n);
  inner.forEach((v, k) => {
    M[k + 1] = v;
  });
  M[0] = ((h[0] + h[1]) * M[1] - h[0] * M[2]) / h[1];
  M[n - 1] = ((h[n - 2] + h[n - 3]) * M[n - 2] - h[n - 2] * M[n - 3]) / h[n - 3];
  return M;
}

/**
 * The planner's reference curve of a polyline, sampled for drawing: a chord-length cubic spline
 * through the points (not-a-knot; the segment itself for two points, a parabola for three), every
 * `step` metres at most (at least 4 samples per input segment, at most `maxSamples` in all).
 * Returns {x, y, tx, ty (unit tangent), kappa [1/m], s [m] (arc length), knotS (s of each input
 * point, duplicates dropped), index (their input indices), length}.
 */
export function referenceCurve(points, { step = 0.5, maxSamples = 20000 } = {}) {
  const { xy, index } = cleanPolyline(points);
  const n = xy.length;
  const u = [0];
  for (let i = 1; i < n; i++) u.push(u[i - 1] + Math.hypot(xy[i][0] - xy[i - 1][0], xy[i][1] - xy[i - 1][1]));
  const total = u[n - 1];
  const px = xy.map((p) => p[0]);
  const py = xy.map((p) => p[1]);
  let evaluate;
  if (n === 2) {
    const dx = (px[1] - px[0]) / total;
    const dy = (py[1] - py[0]) / total;
    evaluate = (i, t) => [px[0] + dx * (u[i] + t), py[0] + dy * (u[i] + t), dx, dy, 0, 0];
  } else if (n === 3) {
    // not-a-knot with three points: the one parabola through them (in u)
    const coef = (v) => {
      const d1 = (v[1] - v[0]) / (u[1] - u[0]);
      const d2 = (v[2] - v[1]) / (u[2] - u[1]);
      const second = (d2 - d1) / (u[2] - u[0]); // half the second derivative
      return [v[0], d1 - second * (u[1] - u[0]), second];
    };
    const cx = coef(px);
    const cy = coef(py);
    evaluate = (i, t) => {
      const w = u[i] + t;
      return [
        cx[0] + cx[1] * w + cx[2] * w * w, cy[0] + cy[1] * w + cy[2] * w * w,
        cx[1] + 2 * cx[2] * w, cy[1] + 2 * cy[2] * w, 2 * cx[2], 2 * cy[2],
      ];
    };
  } else {
    const Mx = notAKnotMoments(u, px);
    const My = notAKnotMoments(u, py);
    const piece = (v, M, i, t) => {
      const hi = u[i + 1] - u[i];
      const A = v[i];
      const B = (v[i + 1] - v[i]) / hi - (hi * (2 * M[i] + M[i + 1])) / 6;
      const C = M[i] / 2;
      const D = (M[i + 1] - M[i]) / (6 * hi);
      return [A + t * (B + t * (C + t * D)), B + t * (2 * C + 3 * D * t), 2 * C + 6 * D * t];
    };
    evaluate = (i, t) => {
      const X = piece(px, Mx, i, t);
      const Y = piece(py, My, i, t);
      return [X[0], Y[0], X[1], Y[1], X[2], Y[2]];
    };
  }
  const spacing = Math.max(step, total / maxSamples);
  const out = { x: [], y: [], tx: [], ty: [], kappa: [], s: [], knotS: [], index, length: 0 };
  let s = 0;
  const push = (v) => {
    const last = out.x.length - 1;
    if (last >= 0) s += Math.hypot(v[0] - out.x[last], v[1] - out.y[last]);
    const speed = Math.hypot(v[2], v[3]);
    out.x.push(v[0]);
    out.y.push(v[1]);
    out.tx.push(v[2] / speed);
    out.ty.push(v[3] / speed);
    out.kappa.push((v[2] * v[5] - v[3] * v[4]) / speed ** 3);
    out.s.push(s);
  };
  for (let i = 0; i < n - 1; i++) {
    const hi = u[i + 1] - u[i];
    const pieces = Math.max(4, Math.ceil(hi / spacing));
    out.knotS.push(s); // the input point's arc length, before the samples of its segment
    for (let k = 0; k < pieces; k++) {
      push(evaluate(i, (hi * k) / pieces));
      if (k === 0) out.knotS[i] = s;
    }
  }
  push(evaluate(n - 2, u[n - 1] - u[n - 2]));
  out.knotS.push(s);
  out.length = out.s[out.s.length - 1];
  return out;
}

/** Linear interpolation of ys over increasing xs at x, held at the ends (numpy.interp). */
export function interp(x, xs, ys) {
  const n = xs.length;
  if (x <= xs[0]) return ys[0];
  if (x >= xs[n - 1]) return ys[n - 1];
  let lo = 0;
  let hi = n - 1;
  while (hi - lo > 1) {
    const mid = (lo + hi) >> 1;
    if (xs[mid] <= x) lo = mid;
    else hi = mid;
  }
  const f = (x - xs[lo]) / (xs[hi] - xs[lo] || 1);
  return ys[lo] + f * (ys[hi] - ys[lo]);
}

/** Width [m] at every sample of `curve` from a request's width: one number, or one per input point
 * of the reference line (interpolated along s, as the planner does). Throws on a malformed width. */
export function widthsAlong(width, curve, name) {
  if (finite(width)) return curve.s.map(() => width);
  if (!Array.isArray(width) || !width.every((w) => finite(w))) {
    throw new Error(`${name} is neither a number nor a list of numbers`);
  }
  if (width.length <= curve.index[curve.index.length - 1]) {
    throw new Error(`${name} has ${width.length} values for more reference points`);
  }
  const w = curve.index.map((i) => width[i]);
  return curve.s.map((s) => interp(s, curve.knotS, w));
}

/**
 * The offset curve at signed offsets d[i] (left positive) of every sample of `curve`, cut where it
 * folds back beyond the centre of curvature (κ·d ≥ 1): a list of polylines [[x, y], …].
 */
export function offsetCurve(curve, d) {
  const runs = [];
  let run = [];
  for (let i = 0; i < curve.x.length; i++) {
    if (curve.kappa[i] * d[i] >= 1) {
      if (run.length > 1) runs.push(run);
      run = [];
      continue;
    }
    run.push([curve.x[i] - curve.ty[i] * d[i], curve.y[i] + curve.tx[i] * d[i]]);
  }
  if (run.length > 1) runs.push(run);
  return runs;
}

/**
 * The band between offsets lower[i] ≤ upper[i] along `curve` as quadrilaterals, each counter-
 * clockwise so that a nonzero fill of them all is their union (folded stretches included).
 */
export function bandQuads(curve, lower, upper) {
  const at = (i, d) => [curve.x[i] - curve.ty[i] * d, curve.y[i] + curve.tx[i] * d];
  const quads = [];
  for (let i = 0; i + 1 < curve.x.length; i++) {
    const q = [at(i, lower[i]), at(i + 1, lower[i + 1]), at(i + 1, upper[i + 1]), at(i, upper[i])];
    if (polygonArea(q) < 0) q.reverse();
    quads.push(q);
  }
  return quads;
}

/** The point and unit normal (left) of `curve` at arc length s. */
export function curveAt(curve, s) {
  const x = interp(s, curve.s, curve.x);
  const y = interp(s, curve.s, curve.y);
  const tx = interp(s, curve.s, curve.tx);
  const ty = interp(s, curve.s, curve.ty);
  const norm = Math.hypot(tx, ty) || 1;
  return { x, y, nx: -ty / norm, ny: tx / norm };
}

/** Signed area of a polygon [[x, y], …] (counter-clockwise positive). */
export function polygonArea(points) {
  let area = 0;
  for (let i = 0; i < points.length; i++) {
    const [x0, y0] = points[i];
    const [x1, y1] = points[(i + 1) % points.length];
    area += x0 * y1 - x1 * y0;
  }
  return area / 2;
}

/** Corners of a box `length × width` centred at (x, y), turned by heading. */
export function boxCorners(x, y, heading, length, width) {
  const c = Math.cos(heading);
  const s = Math.sin(heading);
  const hl = length / 2;
  const hw = width / 2;
  return [
    [x + c * hl - s * hw, y + s * hl + c * hw],
    [x - c * hl - s * hw, y - s * hl + c * hw],
    [x - c * hl + s * hw, y - s * hl - c * hw],
    [x + c * hl + s * hw, y + s * hl - c * hw],
  ];
}

/** Unwrapped copy of angles (numpy.unwrap). */
export function unwrap(angles) {
  const out = [];
  let offset = 0;
  angles.forEach((a, i) => {
    if (i > 0) {
      const jump = a + offset - out[i - 1];
      offset -= 2 * Math.PI * Math.round(jump / (2 * Math.PI));
    }
    out.push(a + offset);
  });
  return out;
}

/** A moving obstacle's pose {x, y, heading} at time t: linear in time, held at the ends (the
 * planner's prediction_at). */
export function predictionAt(prediction, t) {
  const ts = prediction.map((p) => p.t);
  const heading = unwrap(prediction.map((p) => p.heading));
  return {
    x: interp(t, ts, prediction.map((p) => p.x)),
    y: interp(t, ts, prediction.map((p) => p.y)),
    heading: interp(t, ts, heading),
  };
}

/** The kind of an obstacle of a request: "polygon", "circle", "dynamic" or null. */
export function obstacleKind(ob) {
  if (!ob || typeof ob !== "object") return null;
  const kinds = ["polygon", "circle", "prediction"].filter((k) => k in ob);
  if (kinds.length !== 1) return null;
  return kinds[0] === "prediction" ? "dynamic" : kinds[0];
}

/** A trajectory's pose {x, y, heading, v, a, s, d, curvature} at time t (linear between samples). */
export function trajectoryAt(traj, t) {
  const ts = traj.t;
  const pick = (name) => interp(t, ts, traj[name]);
  return {
    x: pick("x"), y: pick("y"), heading: interp(t, ts, unwrap(traj.heading)), v: pick("v"),
    a: pick("a"), s: pick("s"), d: pick("d"), curvature: pick("curvature"),
  };
}

/** Do segments p1–p2 and q1–q2 intersect (touching included)? */
function segmentsIntersect(p1, p2, q1, q2) {
  const orient = (a, b, c) => (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
  const onSegment = (a, b, c) =>
    Math.min(a[0], b[0]) <= c[0] && c[0] <= Math.max(a[0], b[0]) &&
    Math.min(a[1], b[1]) <= c[1] && c[1] <= Math.max(a[1], b[1]);
  const d1 = orient(q1, q2, p1);
  const d2 = orient(q1, q2, p2);
  const d3 = orient(p1, p2, q1);
  const d4 = orient(p1, p2, q2);
  if (((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0))) return true;
  return (
    (d1 === 0 && onSegment(q1, q2, p1)) || (d2 === 0 && onSegment(q1, q2, p2)) ||
    (d3 === 0 && onSegment(p1, p2, q1)) || (d4 === 0 && onSegment(p1, p2, q2))
  );
}

/**
 * Does the polyline [[x, y], …] cross or overlap itself (shapely's `not is_simple`)? Neighbouring
 * segments may share their vertex but not run back over each other. A uniform grid keeps it near
 * linear in the number of points.
 */
export function selfIntersects(points) {
  const pts = points.filter((p, i) => i === 0 || p[0] !== points[i - 1][0] || p[1] !== points[i - 1][1]);
  const n = pts.length - 1; // segments
  if (n < 2) return false;
  let total = 0;
  for (let i = 0; i < n; i++) total += Math.hypot(pts[i + 1][0] - pts[i][0], pts[i + 1][1] - pts[i][1]);
  const cell = Math.max(total / n, 1e-9) * 2;
  const grid = new Map();
  for (let i = 0; i < n; i++) {
    const [a, b] = [pts[i], pts[i + 1]];
    const x0 = Math.floor(Math.min(a[0], b[0]) / cell);
    const x1 = Math.floor(Math.max(a[0], b[0]) / cell);
    const y0 = Math.floor(Math.min(a[1], b[1]) / cell);
    const y1 = Math.floor(Math.max(a[1], b[1]) / cell);
    for (let gx = x0; gx <= x1; gx++) {
      for (let gy = y0; gy <= y1; gy++) {
        const key = `${gx},${gy}`;
        const list = grid.get(key);
        if (list) {
          for (const j of list) {
            if (i - j === 1) {
              // neighbours: only a turn straight back (collinear overlap) crosses
              const p = pts[j];
              const cross = (a[0] - p[0]) * (b[1] - a[1]) - (a[1] - p[1]) * (b[0] - a[0]);
              const dot = (a[0] - p[0]) * (b[0] - a[0]) + (a[1] - p[1]) * (b[1] - a[1]);
              if (cross === 0 && dot < 0) return true;
            } else if (!(j === 0 && i === n - 1 && pts[0][0] === pts[n][0] && pts[0][1] === pts[n][1])) {
              if (segmentsIntersect(pts[j], pts[j + 1], a, b)) return true;
            }
          }
          if (!list.includes(i)) list.push(i);
        } else {
          grid.set(key, [i]);
        }
      }
    }
  }
  return false;
}

/** Does a path fold back: its TransF-κ arc lengths `s` (one per point) not strictly increasing, or
 * the polyline crossing itself (the planner's folds_back)? */
export function foldsBack(points, s) {
  for (let i = 1; i < s.length; i++) if (!(s[i] > s[i - 1])) return true;
  return selfIntersects(points);
}

/** The values of a run file's series: fixed-point deltas, running sum divided by scale. */
export function decodeSeries(series, scale) {
  const out = new Float64Array(series.length);
  let acc = 0;
  for (let i = 0; i < series.length; i++) {
    acc += series[i];
    out[i] = acc / scale;
  }
  return out;
}

/** The points [[x, y], …] of a run file's interleaved xy series. */
export function decodePoints(series, scale) {
  const out = [];
  let x = 0;
  let y = 0;
  for (let i = 0; i + 1 < series.length; i += 2) {
    x += series[i];
    y += series[i + 1];
    out.push([x / scale, y / scale]);
  }
  return out;
}

/** Bounding box {minX, minY, maxX, maxY} of point lists, or null when there is no finite point. */
export function bounds(...lists) {
  let minX = Infinity;
  let minY = Infinity;
  let maxX = -Infinity;
  let maxY = -Infinity;
  for (const list of lists) {
    for (const p of list) {
      if (!finite(p[0], p[1])) continue;
      minX = Math.min(minX, p[0]);
      maxX = Math.max(maxX, p[0]);
      minY = Math.min(minY, p[1]);
      maxY = Math.max(maxY, p[1]);
    }
  }
  return minX <= maxX ? { minX, minY, maxX, maxY } : null;
}
