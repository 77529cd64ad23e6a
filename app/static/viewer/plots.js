// Small line charts in SVG: v(t), a(t), κ(s), d(s). A chart holds series {x, y, cls}; its cursor
// (the time slider's t or the matching s) moves without redrawing the rest.

const NS = "http://www.w3.org/2000/svg";
const MARGIN = { left: 46, right: 10, top: 16, bottom: 18 };

function el(name, attrs = {}, parent = null) {
  const node = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, String(v));
  if (parent) parent.appendChild(node);
  return node;
}

/** About `count` round tick values covering [lo, hi]. */
export function ticks(lo, hi, count = 4) {
  if (!(hi > lo)) return [lo];
  const raw = (hi - lo) / count;
  const mag = 10 ** Math.floor(Math.log10(raw));
  const step = [1, 2, 2.5, 5, 10].map((f) => f * mag).find((s) => s >= raw) ?? 10 * mag;
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) out.push(Math.abs(v) < step * 1e-9 ? 0 : v);
  return out;
}

function fmt(v) {
  const a = Math.abs(v);
  if (a === 0) return "0";
  if (a >= 1000 || a < 0.01) return v.toExponential(0);
  return String(Number(v.toPrecision(3)));
}

export class Plot {
  constructor(svg, { title, height = 132 }) {
    this.svg = svg;
    this.title = title;
    this.height = height;
    this.series = [];
    this.cursorX = null;
  }

  /** Replace the series: [{x: [], y: [], cls: "main" | "history" | "faint" | "bound" | "limit" | …}]. */
  setData(series) {
    this.series = series.filter((s) => s && s.x && s.x.length);
    this.render();
  }

  setCursor(x) {
    this.cursorX = x;
    this.drawCursor();
  }

  domain() {
    let x0 = Infinity;
    let x1 = -Infinity;
    let y0 = Infinity;
    let y1 = -Infinity;
    for (const s of this.series) {
      for (let i = 0; i < s.x.length; i++) {
        const x = s.x[i];
        const y = s.y[i];
        if (!Number.isFinite(x) || !Number.isFinite(y)) continue;
        x0 = Math.min(x0, x);
        x1 = Math.max(x1, x);
        if (s.cls === "limit" && !s.fit) continue; // limits show when near the data, never set the scale
        y0 = Math.min(y0, y);
        y1 = Math.max(y1, y);
      }
    }
    if (!(x1 >= x0)) return null;
    if (!(y1 >= y0)) {
      y0 = -1;
      y1 = 1;
    }
    if (x1 === x0) x1 = x0 + 1;
    const pad = (y1 - y0) * 0.08 || Math.max(Math.abs(y0) * 0.1, 0.1);
    return { x0, x1, y0: y0 - pad, y1: y1 + pad };
  }

  render() {
    const svg = this.svg;
    svg.replaceChildren();
    const width = Math.max(svg.getBoundingClientRect().width || 0, 200);
    const height = this.height;
    svg.setAttribute("viewBox", `0 0 ${width} ${height}`);
    this.width = width;
    const title = el("text", { class: "title", x: MARGIN.left, y: 11 }, svg);
    title.textContent = this.title;
    const dom = this.domain();
    svg.dataset.series = String(this.series.length);
    svg.dataset.points = String(this.series.filter((s) => s.cls === "main").reduce((n, s) => n + s.x.length, 0));
    if (!dom) {
      const none = el("text", { class: "tick", x: width / 2, y: height / 2, "text-anchor": "middle" }, svg);
      none.textContent = "no data";
      this.dom = null;
      return;
    }
    this.dom = dom;
    const iw = width - MARGIN.left - MARGIN.right;
    const ih = height - MARGIN.top - MARGIN.bottom;
    this.sx = (x) => MARGIN.left + ((x - dom.x0) / (dom.x1 - dom.x0)) * iw;
    this.sy = (y) => MARGIN.top + (1 - (y - dom.y0) / (dom.y1 - dom.y0)) * ih;
    el("rect", { class: "frame", x: MARGIN.left, y: MARGIN.top, width: iw, height: ih }, svg);
    for (const v of ticks(dom.y0, dom.y1)) {
      el("line", { class: "grid", x1: MARGIN.left, x2: MARGIN.left + iw, y1: this.sy(v), y2: this.sy(v) }, svg);
      const t = el("text", { class: "tick", x: MARGIN.left - 4, y: this.sy(v) + 3, "text-anchor": "end" }, svg);
      t.textContent = fmt(v);
    }
    for (const v of ticks(dom.x0, dom.x1, 5)) {
      el("line", { class: "grid", x1: this.sx(v), x2: this.sx(v), y1: MARGIN.top, y2: MARGIN.top + ih }, svg);
      const t = el("text", { class: "tick", x: this.sx(v), y: height - 5, "text-anchor": "middle" }, svg);
      t.textContent = fmt(v);
    }
    const clip = `clip-${svg.id}`;
    const defs = el("defs", {}, svg);
    const cp = el("clipPath", { id: clip }, defs);
    el("rect", { x: MARGIN.left, y: MARGIN.top, width: iw, height: ih }, cp);
    const body = el("g", { "clip-path": `url(#${clip})` }, svg);
    for (const s of this.series) {
      let d = "";
      let pen = false;
      for (let i = 0; i < s.x.length; i++) {
        if (!Number.isFinite(s.x[i]) || !Number.isFinite(s.y[i])) {
          pen = false;
          continue;
        }
        d += `${pen ? "L" : "M"}${this.sx(s.x[i]).toFixed(1)} ${this.sy(s.y[i]).toFixed(1)}`;
        pen = true;
      }
      if (d) el("path", { class: `series ${s.cls || "main"}`, d }, body);
    }
    this.cursorGroup = el("g", {}, svg);
    this.drawCursor();
  }

  drawCursor() {
    if (!this.cursorGroup || !this.dom) return;
    this.cursorGroup.replaceChildren();
    const x = this.cursorX;
    if (x === null || !Number.isFinite(x) || x < this.dom.x0 || x > this.dom.x1) return;
    const X = this.sx(x);
    el("line", { class: "cursor", x1: X, x2: X, y1: MARGIN.top, y2: this.height - MARGIN.bottom }, this.cursorGroup);
    for (const s of this.series) {
      if (s.cls !== "main" && s.cls !== "history") continue;
      const y = valueAt(s, x);
      if (y !== null) el("circle", { class: "dot", cx: X, cy: this.sy(y), r: 2.5 }, this.cursorGroup);
    }
  }
}

/** y of a series at x (linear between its points; null outside them). */
function valueAt(s, x) {
  const n = s.x.length;
  if (!n || x < s.x[0] || x > s.x[n - 1]) return null;
  for (let i = 1; i < n; i++) {
    if (s.x[i] >= x) {
      const f = (x - s.x[i - 1]) / (s.x[i] - s.x[i - 1] || 1);
      return s.y[i - 1] + f * (s.y[i] - s.y[i - 1]);
    }
  }
  return s.y[n - 1];
}
