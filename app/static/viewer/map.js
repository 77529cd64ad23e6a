// The map: an SVG whose world group is flipped (y up) inside a viewBox in world units, so panning
// and zooming only change the viewBox. Strokes keep their pixel width (vector-effect in the CSS);
// labels are resized to stay 12 px. Layers are <g> elements drawn in a fixed order.

const NS = "http://www.w3.org/2000/svg";

export const LAYERS = [
  "road", "lane", "reference", "goal", "predictions", "obstacles", "candidates", "ghosts",
  "footprints", "driven", "trajectory", "ego", "points", "labels",
];

export function el(name, attrs = {}, parent = null) {
  const node = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) {
    if (v !== undefined && v !== null) node.setAttribute(k, String(v));
  }
  if (parent) parent.appendChild(node);
  return node;
}

/** SVG path data of a polyline [[x, y], …] (world coordinates, y flipped by the group). */
export function pathData(points, close = false) {
  let d = "";
  for (let i = 0; i < points.length; i++) {
    const [x, y] = points[i];
    d += `${i ? "L" : "M"}${x.toFixed(3)} ${(-y).toFixed(3)}`;
  }
  return close && d ? `${d}Z` : d;
}

export class MapView {
  constructor(svg) {
    this.svg = svg;
    this.world = el("g", { class: "world" }, svg);
    this.layers = {};
    for (const name of LAYERS) this.layers[name] = el("g", { "data-layer": name }, this.world);
    this.view = { x: -50, y: -50, w: 100, h: 100 }; // viewBox in (x, −y)
    this.home = null;
    this.extent = null; // everything drawn (the "all" button)
    this.onZoom = () => {};
    this.installHandlers();
    new ResizeObserver(() => this.apply()).observe(svg);
  }

  clear(...names) {
    for (const name of names.length ? names : LAYERS) this.layers[name].replaceChildren();
  }

  setVisible(name, visible) {
    this.layers[name].classList.toggle("hidden-layer", !visible);
  }

  /** Pixels per metre at the current zoom. */
  scale() {
    const r = this.svg.getBoundingClientRect();
    return Math.min(r.width / this.view.w, r.height / this.view.h) || 1;
  }

  apply() {
    const r = this.svg.getBoundingClientRect();
    if (!r.width || !r.height) return;
    // keep the view's centre and the larger of its sizes at the element's aspect ratio
    const k = Math.min(r.width / this.view.w, r.height / this.view.h);
    const cx = this.view.x + this.view.w / 2;
    const cy = this.view.y + this.view.h / 2;
    this.view.w = r.width / k;
    this.view.h = r.height / k;
    this.view.x = cx - this.view.w / 2;
    this.view.y = cy - this.view.h / 2;
    const { x, y, w, h } = this.view;
    this.svg.setAttribute("viewBox", `${x} ${y} ${w} ${h}`);
    this.svg.dataset.zoom = k.toFixed(4);
    this.onZoom(1 / k);
  }

  /** Show the box {minX, minY, maxX, maxY} (world, y up) with a margin; remembered for "fit". */
  fit(box, remember = true) {
    if (!box) return;
    if (remember) this.home = box;
    const pad = Math.max(box.maxX - box.minX, box.maxY - box.minY) * 0.06 + 2;
    this.view = { x: box.minX - pad, y: -box.maxY - pad, w: box.maxX - box.minX + 2 * pad, h: box.maxY - box.minY + 2 * pad };
    this.apply(); // widens the narrower side to the element's aspect ratio, around the centre
  }

  fitHome() {
    if (this.home) this.fit(this.home, false);
  }

  /** Zoom by `factor` (> 1: in) around the client point (px, py), default the centre. */
  zoom(factor, px = null, py = null) {
    const r = this.svg.getBoundingClientRect();
    const fx = px === null ? 0.5 : (px - r.left) / r.width;
    const fy = py === null ? 0.5 : (py - r.top) / r.height;
    const wx = this.view.x + fx * this.view.w;
    const wy = this.view.y + fy * this.view.h;
    const w = Math.min(Math.max(this.view.w / factor, 0.5), 1e6);
    const h = (this.view.h * w) / this.view.w;
    this.view = { x: wx - fx * w, y: wy - fy * h, w, h };
    this.apply();
  }

  installHandlers() {
    const svg = this.svg;
    let drag = null;
    svg.addEventListener("pointerdown", (e) => {
      if (e.button !== 0) return;
      drag = { x: e.clientX, y: e.clientY, view: { ...this.view }, id: e.pointerId };
      svg.setPointerCapture(e.pointerId);
      svg.classList.add("dragging");
    });
    svg.addEventListener("pointermove", (e) => {
      if (!drag || e.pointerId !== drag.id) return;
      const k = this.scale();
      this.view.x = drag.view.x - (e.clientX - drag.x) / k;
      this.view.y = drag.view.y - (e.clientY - drag.y) / k;
      this.apply();
    });
    const end = (e) => {
      if (drag && e.pointerId === drag.id) {
        drag = null;
        svg.classList.remove("dragging");
      }
    };
    svg.addEventListener("pointerup", end);
    svg.addEventListener("pointercancel", end);
    svg.addEventListener(
      "wheel",
      (e) => {
        e.preventDefault();
        this.zoom(Math.exp(-e.deltaY * (e.deltaMode === 1 ? 0.05 : 0.0015)), e.clientX, e.clientY);
      },
      { passive: false },
    );
    svg.addEventListener("dblclick", () => this.fitHome());
  }
}
