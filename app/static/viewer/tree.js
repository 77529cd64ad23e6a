// The diagnostics as text: any JSON value as a tree of tables, so that fields the service adds
// show without changes here; an object of numbers whose key ends in `_ms` (stage times) gets bars.

/** A number for people: integers as they are, others to `digits` decimals or in exponent form. */
export function num(v, digits = 3) {
  if (typeof v !== "number") return String(v);
  if (Number.isInteger(v)) return String(v);
  const a = Math.abs(v);
  if (a !== 0 && (a < 1e-3 || a >= 1e6)) return v.toExponential(2);
  return String(Number(v.toFixed(digits)));
}

/** Any JSON value as a tree of tables: new diagnostics fields show without changes here. Objects
 * of numbers whose key ends in `_ms` (stage times) get bars. */
export function tree(value, key = "") {
  if (value === null || value === undefined) {
    const span = document.createElement("span");
    span.className = "null";
    span.textContent = "null";
    return span;
  }
  if (Array.isArray(value)) {
    if (value.every((v) => typeof v !== "object" || v === null) && value.length <= 12) {
      const span = document.createElement("span");
      span.textContent = `[${value.map((v) => (typeof v === "number" ? num(v) : JSON.stringify(v))).join(", ")}]`;
      return span;
    }
    const details = document.createElement("details");
    const summary = document.createElement("summary");
    summary.textContent = `${value.length} items`;
    details.appendChild(summary);
    value.slice(0, 200).forEach((v, i) => details.appendChild(tree({ [i]: v })));
    return details;
  }
  if (typeof value === "object") {
    const entries = Object.entries(value);
    const timing = key.endsWith("_ms") && entries.length && entries.every(([, v]) => typeof v === "number");
    const biggest = timing ? Math.max(...entries.map(([, v]) => Math.abs(v)), 1e-9) : 0;
    const table = document.createElement("table");
    for (const [k, v] of entries) {
      const row = table.insertRow();
      row.dataset.key = k;
      const kc = row.insertCell();
      kc.className = "key";
      kc.textContent = k;
      const vc = row.insertCell();
      if (timing) {
        const bar = document.createElement("span");
        bar.className = "bar";
        bar.style.width = `${Math.round((80 * Math.abs(v)) / biggest)}px`;
        vc.append(bar, document.createTextNode(`${num(v, 2)} ms`));
      } else {
        vc.appendChild(tree(v, k));
      }
    }
    return table;
  }
  const span = document.createElement("span");
  if (typeof value === "string") span.className = "str";
  span.textContent = typeof value === "number" ? num(value) : String(value);
  return span;
}
