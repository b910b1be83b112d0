/* crlbswarm campaign report: draws the page from the JSON of #crlb-data.
 *
 * Vanilla JavaScript and inline SVG, written for this page: no library, no network.
 * Missing values (null in the data: a quantity that does not exist for a run, such as the
 * convergence time of a run that did not converge) are shown as a dash, sorted last in
 * either direction, and left out of medians, box plots and histograms.
 *
 * State for tests and scripts: window.crlbReport (see the end of this file).
 */
(function () {
  "use strict";

  const DATA = JSON.parse(document.getElementById("crlb-data").textContent);
  const ROOT = document.getElementById("report");
  const SVG_NS = "http://www.w3.org/2000/svg";
  const DASH = "\u2014";
  const COLORS = {
    converged: "#2e8b57",
    timeout: "#e08a00",
    stuck: "#7b52ab",
    collision: "#c8302c",
  };
  const OTHER_COLORS = ["#607d8b", "#8d6e63", "#00838f", "#ad1457"];
  /** Most variants drawn in a chart (the first ones in the variant table's order). */
  const MAX_CHART_VARIANTS = 60;
  /** Most runs listed in the runs table at once (the first ones in its order). */
  const MAX_RUN_TABLE_ROWS = 2000;

  // -- small helpers ------------------------------------------------------------------------
  /** An HTML element with attributes and children (strings become text nodes). */
  function h(tag, attrs, ...children) {
    const node = document.createElement(tag);
    setAttrs(node, attrs);
    append(node, children);
    return node;
  }

  /** An SVG element with attributes and children. */
  function s(tag, attrs, ...children) {
    const node = document.createElementNS(SVG_NS, tag);
    setAttrs(node, attrs);
    append(node, children);
    return node;
  }

  function setAttrs(node, attrs) {
    for (const [k, v] of Object.entries(attrs || {})) {
      if (v === null || v === undefined || v === false) continue;
      if (k === "onclick") node.addEventListener("click", v);
      else node.setAttribute(k, String(v));
    }
  }

  function append(node, children) {
    for (const child of children.flat()) {
      if (child === null || child === undefined || child === false) continue;
      node.append(child instanceof Node ? child : document.createTextNode(String(child)));
    }
  }

  /** A value as shown, null as a dash. Numbers by ``format``: "int" whole, "short" in
   * their shortest form to 6 significant digits, a count of significant digits (default 4;
   * an exponent below 1e-3 and from 1e7 up). */
  function fmt(v, format) {
    if (v === null || v === undefined || (typeof v === "number" && !Number.isFinite(v))) {
      return DASH;
    }
    if (typeof v !== "number") return String(v);
    if (format === "int") return String(v);
    if (format === "short") return String(Number(v.toPrecision(6)));
    const digits = typeof format === "number" ? format : 4;
    const a = Math.abs(v);
    if (a !== 0 && (a < 1e-3 || a >= 1e7)) return v.toExponential(digits - 1);
    if (a >= Math.pow(10, digits)) return v.toFixed(0);
    return v.toPrecision(digits);
  }

  /** A tick label: as short as the tick value allows. */
  function tickText(t) {
    const a = Math.abs(t);
    if (a !== 0 && (a < 1e-3 || a >= 1e6)) return t.toExponential(0);
    return String(Number(t.toPrecision(6)));
  }

  function withUnit(label, unit) {
    return unit ? `${label} (${unit})` : label;
  }

  function outcomeColor(name) {
    if (COLORS[name]) return COLORS[name];
    const i = DATA.outcomes.indexOf(name);
    return OTHER_COLORS[Math.max(i, 0) % OTHER_COLORS.length];
  }

  function variantById(id) {
    return DATA.variants.find((v) => v.id === id);
  }

  /** The variant's parameters as text; short: each field by the last part of its name. */
  function paramText(variant, limit) {
    const name = (f) => (limit ? f.slice(f.lastIndexOf(".") + 1) : f);
    const value = (v) => (limit ? fmt(v, "short") : v === null ? DASH : String(v));
    const text = DATA.fields.map((f) => `${name(f)}=${value(variant.params[f])}`).join(", ") || "base";
    return limit && text.length > limit ? text.slice(0, limit - 1) + "\u2026" : text;
  }

  // -- sortable tables ----------------------------------------------------------------------
  /** Order of two cells: missing values last whatever the direction; numbers by value,
   * text by code points. */
  function compareCells(a, b, type, dir) {
    const missingA = a === null || a === undefined || (typeof a === "number" && Number.isNaN(a));
    const missingB = b === null || b === undefined || (typeof b === "number" && Number.isNaN(b));
    if (missingA || missingB) return missingA === missingB ? 0 : missingA ? 1 : -1;
    let c;
    if (type === "number") c = a - b;
    else {
      const x = String(a);
      const y = String(b);
      c = x < y ? -1 : x > y ? 1 : 0;
    }
    return dir === "desc" ? -c : c;
  }

  /** A table whose columns sort by a click on their header (again: the other direction).
   * columns: [{key, label, title, type: "number" | "text", format (see fmt), swatch(value)}]
   * rows: [{id, cells: [...values]}] */
  class SortableTable {
    constructor(id, columns, rows, options) {
      this.columns = columns;
      this.rows = rows;
      this.order = rows.map((_, i) => i);
      this.sortKey = null;
      this.sortDir = null;
      this.options = options || {};
      this.table = h("table", { id, class: "sortable" });
      this.thead = h("thead");
      this.tbody = h("tbody");
      this.table.append(this.thead, this.tbody);
      this.note = h("p", { class: "table-note" });
      this.element = h("div", { class: "table-wrap" }, this.table, this.note);
      this.renderHead();
      this.renderBody();
    }

    columnIndex(col) {
      if (typeof col === "number") return col;
      let i = this.columns.findIndex((c) => c.key === col);
      if (i < 0) i = this.columns.findIndex((c) => c.label === col);
      if (i < 0) throw new Error(`no column ${col}`);
      return i;
    }

    /** Sort by a column (key, label or index), "asc" or "desc"; without a direction,
     * ascending first, then toggling. */
    sortBy(col, dir) {
      const i = this.columnIndex(col);
      const column = this.columns[i];
      if (dir !== "asc" && dir !== "desc") {
        dir = this.sortKey === column.key && this.sortDir === "asc" ? "desc" : "asc";
      }
      this.sortKey = column.key;
      this.sortDir = dir;
      const rows = this.rows;
      this.order = rows
        .map((_, k) => k)
        .sort((p, q) => compareCells(rows[p].cells[i], rows[q].cells[i], column.type, dir) || p - q);
      this.renderHead();
      this.renderBody();
      if (this.options.onSort) this.options.onSort();
      return this.state();
    }

    state() {
      return { column: this.sortKey, dir: this.sortDir };
    }

    renderHead() {
      const tr = h("tr");
      this.columns.forEach((c, i) => {
        const active = c.key === this.sortKey;
        const arrow = active ? (this.sortDir === "asc" ? " \u25b2" : " \u25bc") : "";
        const th = h(
          "th",
          {
            scope: "col",
            class: c.type === "number" ? "num" : "text",
            title: (c.title || c.label) + " \u2014 click to sort",
            "data-key": c.key,
            "aria-sort": active ? (this.sortDir === "asc" ? "ascending" : "descending") : "none",
            tabindex: 0,
          },
          c.label,
          h("span", { class: "sort-indicator", "aria-hidden": "true" }, arrow)
        );
        th.addEventListener("click", () => this.sortBy(i));
        th.addEventListener("keydown", (e) => {
          if (e.key === "Enter" || e.key === " ") {
            e.preventDefault();
            this.sortBy(i);
          }
        });
        tr.append(th);
      });
      this.thead.replaceChildren(tr);
    }

    renderBody() {
      const limit = this.options.limit || Infinity;
      const shown = this.order.slice(0, limit);
      const fragment = document.createDocumentFragment();
      for (const k of shown) {
        const row = this.rows[k];
        const tr = h("tr", { "data-id": row.id });
        if (this.options.selected && this.options.selected() === row.id) tr.className = "selected";
        row.cells.forEach((v, i) => {
          const c = this.columns[i];
          const td = h("td", { class: c.type === "number" ? "num" : "text" });
          if (c.swatch) td.append(h("span", { class: "swatch", style: `background:${c.swatch(v)}` }));
          td.append(fmt(v, c.format));
          if (v === null || v === undefined) td.title = this.options.missingTitle || "no value";
          tr.append(td);
        });
        if (this.options.onRowClick) tr.addEventListener("click", () => this.options.onRowClick(row.id));
        fragment.append(tr);
      }
      this.tbody.replaceChildren(fragment);
      this.note.textContent =
        this.order.length > shown.length
          ? `Showing the first ${shown.length} of ${this.order.length} rows in this order.`
          : "";
    }

    /** The rows in their current order, as arrays of values (null for missing). */
    currentRows() {
      return this.order.map((k) => this.rows[k].cells.slice());
    }

    currentIds() {
      return this.order.map((k) => this.rows[k].id);
    }
  }

  // -- scales and axes ----------------------------------------------------------------------
  function niceStep(span, n) {
    const raw = span / Math.max(n, 1);
    const p = Math.pow(10, Math.floor(Math.log10(raw)));
    const m = raw / p;
    return (m < 1.5 ? 1 : m < 3.5 ? 2 : m < 7.5 ? 5 : 10) * p;
  }

  function linearTicks(lo, hi, n) {
    if (!(hi > lo)) return [lo];
    const step = niceStep(hi - lo, n);
    const ticks = [];
    for (let t = Math.ceil(lo / step - 1e-9) * step; t <= hi + step * 1e-9; t += step) {
      ticks.push(Math.abs(t) < step * 1e-9 ? 0 : Number(t.toPrecision(12)));
    }
    return ticks;
  }

  function logTicks(lo, hi) {
    const ticks = [];
    for (let k = Math.floor(Math.log10(lo)); k <= Math.ceil(Math.log10(hi)); k++) {
      for (const m of [1, 2, 5]) {
        const t = m * Math.pow(10, k);
        if (t >= lo * (1 - 1e-9) && t <= hi * (1 + 1e-9)) ticks.push(Number(t.toPrecision(12)));
      }
    }
    const decades = ticks.filter((t) => Math.abs(Math.log10(t) - Math.round(Math.log10(t))) < 1e-9);
    return decades.length >= 3 ? decades : ticks;
  }

  /** A function from value to pixel on [x0, x1] for the distribution's domain. */
  function scaleOf(dist, x0, x1) {
    const lo = dist.edges[0];
    const hi = dist.edges[dist.edges.length - 1];
    if (dist.log) {
      const a = Math.log10(lo);
      const b = Math.log10(hi);
      return (v) => x0 + ((Math.log10(Math.max(v, lo)) - a) / (b - a || 1)) * (x1 - x0);
    }
    return (v) => x0 + ((v - lo) / (hi - lo || 1)) * (x1 - x0);
  }

  function xAxis(svg, dist, x, x0, x1, y) {
    const lo = dist.edges[0];
    const hi = dist.edges[dist.edges.length - 1];
    const ticks = dist.log ? logTicks(lo, hi) : linearTicks(lo, hi, 5);
    svg.append(s("line", { x1: x0, x2: x1, y1: y, y2: y, class: "axis" }));
    for (const t of ticks) {
      const px = x(t);
      svg.append(s("line", { x1: px, x2: px, y1: y, y2: y + 4, class: "axis" }));
      svg.append(s("text", { x: px, y: y + 15, class: "tick", "text-anchor": "middle" }, tickText(t)));
    }
    const label = withUnit(dist.label, dist.unit) + (dist.log ? ", log scale" : "");
    svg.append(s("text", { x: (x0 + x1) / 2, y: y + 32, class: "axis-label", "text-anchor": "middle" }, label));
  }

  // -- charts -------------------------------------------------------------------------------
  const CHART_W = 640;
  const LEFT = 230;
  const RIGHT = 20;
  const ROW_H = 18;

  function rowLabel(svg, variant, y, selected) {
    const label = s("text", { x: LEFT - 8, y: y + 4, class: selected ? "row-label selected" : "row-label", "text-anchor": "end" },
      `${variant.id}: ${paramText(variant, 34)}`);
    label.append(s("title", {}, `variant ${variant.id}: ${paramText(variant)}`));
    svg.append(label);
  }

  function chartVariants() {
    return state.variantTable.currentIds().slice(0, MAX_CHART_VARIANTS).map(variantById);
  }

  function rowBand(svg, variant, y, selected) {
    const band = s("rect", { x: 0, y: y - ROW_H / 2, width: CHART_W, height: ROW_H, class: selected ? "band selected" : "band", "data-id": variant.id });
    band.addEventListener("click", () => selectVariant(variant.id));
    svg.append(band);
  }

  /** Stacked bars of each variant's outcome fractions. */
  function outcomeChart() {
    const variants = chartVariants();
    const top = 10;
    const height = top + variants.length * ROW_H + 44;
    const svg = s("svg", { viewBox: `0 0 ${CHART_W} ${height}`, class: "chart", role: "img", "aria-label": "outcomes of the runs of each variant" });
    const x = (f) => LEFT + f * (CHART_W - LEFT - RIGHT);
    variants.forEach((v, i) => {
      const y = top + (i + 0.5) * ROW_H;
      const selected = v.id === state.selected;
      rowBand(svg, v, y, selected);
      rowLabel(svg, v, y, selected);
      let acc = 0;
      for (const name of DATA.outcomes) {
        const count = v.counts[name] || 0;
        if (!count || !v.runs) continue;
        const f = count / v.runs;
        const rect = s("rect", { x: x(acc), y: y - 6, width: Math.max(x(acc + f) - x(acc), 0.5), height: 12, fill: outcomeColor(name), class: "bar" });
        rect.append(s("title", {}, `variant ${v.id}: ${name} ${count} of ${v.runs} runs (${(100 * f).toFixed(1)} %)`));
        svg.append(rect);
        acc += f;
      }
      if (!v.runs) svg.append(s("text", { x: LEFT + 4, y: y + 4, class: "empty" }, "no finished runs"));
    });
    const dist = { edges: [0, 100], log: false, label: "share of the variant's runs", unit: "%" };
    xAxis(svg, dist, (p) => x(p / 100), LEFT, CHART_W - RIGHT, top + variants.length * ROW_H + 4);
    return svg;
  }

  /** Box plots of one distribution metric, one row per variant. */
  function boxPlot(dist) {
    const variants = chartVariants();
    const top = 10;
    const height = top + variants.length * ROW_H + 44;
    const svg = s("svg", { viewBox: `0 0 ${CHART_W} ${height}`, class: "chart", role: "img", "aria-label": `box plots of ${dist.label}` });
    const x = scaleOf(dist, LEFT, CHART_W - RIGHT);
    variants.forEach((v, i) => {
      const y = top + (i + 0.5) * ROW_H;
      const st = v.stats[dist.key];
      const selected = v.id === state.selected;
      rowBand(svg, v, y, selected);
      rowLabel(svg, v, y, selected);
      if (!st.n) {
        svg.append(s("text", { x: LEFT + 4, y: y + 4, class: "empty" }, `no value (${st.missing} runs: ${dist.missing})`));
        return;
      }
      const g = s("g", { class: "box" });
      g.append(s("line", { x1: x(st.min), x2: x(st.max), y1: y, y2: y, class: "whisker" }));
      for (const w of [st.min, st.max]) g.append(s("line", { x1: x(w), x2: x(w), y1: y - 4, y2: y + 4, class: "whisker" }));
      g.append(s("rect", { x: x(st.q1), y: y - 6, width: Math.max(x(st.q3) - x(st.q1), 1), height: 12, class: "iqr" }));
      g.append(s("line", { x1: x(st.median), x2: x(st.median), y1: y - 7, y2: y + 7, class: "median" }));
      const missing = st.missing ? `; ${st.missing} without a value (${dist.missing})` : "";
      g.append(s("title", {}, `variant ${v.id}: min ${fmt(st.min, dist.digits)}, quartiles ${fmt(st.q1, dist.digits)} / ${fmt(st.median, dist.digits)} / ${fmt(st.q3, dist.digits)}, max ${fmt(st.max, dist.digits)} ${dist.unit}; ${st.n} runs with a value${missing}`));
      svg.append(g);
    });
    xAxis(svg, dist, x, LEFT, CHART_W - RIGHT, top + variants.length * ROW_H + 4);
    return svg;
  }

  /** Histogram of one distribution metric for one variant (bins shared by all variants). */
  function histogram(dist, variant) {
    const W = 420;
    const H = 210;
    const left = 46;
    const right = 12;
    const top = 30;
    const bottom = H - 40;
    const counts = variant.hist[dist.key];
    const st = variant.stats[dist.key];
    const svg = s("svg", { viewBox: `0 0 ${W} ${H}`, class: "chart hist", role: "img", "aria-label": `histogram of ${dist.label}, variant ${variant.id}` });
    const x = scaleOf(dist, left, W - right);
    const maxCount = Math.max(1, ...counts);
    const y = (c) => bottom - (c / maxCount) * (bottom - top);
    for (const t of linearTicks(0, maxCount, 4).filter(Number.isInteger)) {
      svg.append(s("line", { x1: left - 4, x2: W - right, y1: y(t), y2: y(t), class: t ? "gridline" : "axis" }));
      svg.append(s("text", { x: left - 6, y: y(t) + 4, class: "tick", "text-anchor": "end" }, String(t)));
    }
    svg.append(s("text", { x: 12, y: (top + bottom) / 2, class: "axis-label", "text-anchor": "middle", transform: `rotate(-90 12 ${(top + bottom) / 2})` }, "runs"));
    counts.forEach((c, i) => {
      if (!c) return;
      const a = x(dist.edges[i]);
      const b = x(dist.edges[i + 1]);
      const bar = s("rect", { x: a + 0.5, y: y(c), width: Math.max(b - a - 1, 0.5), height: bottom - y(c), class: "hbar" });
      bar.append(s("title", {}, `${fmt(dist.edges[i])} to ${fmt(dist.edges[i + 1])} ${dist.unit}: ${c} runs`));
      svg.append(bar);
    });
    if (st.median !== null) {
      svg.append(s("line", { x1: x(st.median), x2: x(st.median), y1: top - 4, y2: bottom, class: "median-line" }));
    }
    xAxis(svg, dist, x, left, W - right, bottom);
    const note = `${st.n} of ${variant.runs} runs with a value, median ${fmt(st.median, dist.digits)} ${dist.unit}`;
    svg.append(s("text", { x: left, y: 10, class: "hist-note" }, note));
    if (st.missing) svg.append(s("text", { x: left, y: 22, class: "hist-note" }, `${st.missing} without a value (${dist.missing})`));
    return svg;
  }

  // -- sections -------------------------------------------------------------------------------
  const state = { selected: null, variantTable: null, runTable: null };

  function header() {
    const spec = DATA.spec || {};
    const expected = DATA.variants.reduce((n, v) => n + (v.expected || 0), 0);
    const totals = {};
    for (const v of DATA.variants) for (const [k, c] of Object.entries(v.counts)) totals[k] = (totals[k] || 0) + c;
    const complete = DATA.variants.every((v) => v.expected === null || v.runs >= v.expected);
    return h("header", {},
      h("h1", {}, DATA.title),
      h("p", { class: "subtitle" }, `Folder ${DATA.folder} \u00b7 written by crlbswarm ${DATA.version}`),
      h("div", { class: "cards" },
        card("variants", DATA.variants.length),
        card("runs", DATA.total_runs + (expected ? ` of ${expected}` : "")),
        ...DATA.outcomes.map((o) => card(o, totals[o] || 0, outcomeColor(o)))),
      complete ? null : h("p", { class: "warning", id: "incomplete" },
        "This campaign is not finished: some variants have fewer runs than its seeds. " +
        "Run the same crlbswarm sweep command again to resume it, then rebuild this report."),
      h("p", {}, `Base scenario: ${spec.base_name || spec.base || "?"}` +
        (spec.base_description ? ` \u2014 ${spec.base_description}` : "")));
  }

  function card(label, value, color) {
    return h("div", { class: "card", "data-card": label },
      h("div", { class: "card-value", style: color ? `color:${color}` : null }, String(value)),
      h("div", { class: "card-label" }, label));
  }

  function sweepSection() {
    const spec = DATA.spec || {};
    const seeds = spec.seeds || {};
    const items = [
      ["base", spec.base],
      ["seeds", seeds.count !== undefined ? `${seeds.start} .. ${seeds.start + seeds.count - 1} (${seeds.count} per variant)` : null],
      ["batch size", spec.batch_size],
    ];
    if (spec.grid) for (const [k, vals] of Object.entries(spec.grid)) items.push([`grid: ${k}`, vals.map((x) => JSON.stringify(x)).join(", ")]);
    if (spec.random) {
      items.push(["random sample", `${spec.random.samples} variants, seed ${spec.random.seed}`]);
      for (const [k, d] of Object.entries(spec.random.fields || {})) {
        items.push([`random: ${k}`, d.uniform ? `uniform in [${d.uniform.join(", ")}]` : `one of ${JSON.stringify(d.choice)}`]);
      }
    }
    const dl = h("dl", { class: "spec" });
    for (const [k, v] of items) if (v !== null && v !== undefined) dl.append(h("dt", {}, k), h("dd", {}, String(v)));
    return h("section", { id: "sweep" },
      h("h2", {}, "Sweep parameters"),
      h("p", {}, "Each variant is the base scenario with the fields below changed; the table " +
        "of variants gives each one's values."),
      dl,
      DATA.spec_toml ? h("details", {}, h("summary", {}, "spec.toml as given"), h("pre", {}, DATA.spec_toml)) : null);
  }

  function variantColumns() {
    const cols = [{ key: "variant", label: "variant", type: "number", format: "int", title: "variant id (the folder runs/variant=<id>)" }];
    for (const f of DATA.fields) cols.push({ key: `param:${f}`, label: f, type: DATA.field_kinds[f], format: "short", title: `sweep parameter ${f}` });
    cols.push({ key: "runs", label: "runs", type: "number", format: "int", title: "finished runs of the variant" });
    for (const o of DATA.outcomes) cols.push({ key: `outcome:${o}`, label: o, type: "number", format: "int", title: `runs whose outcome is ${o}`, swatch: () => outcomeColor(o) });
    for (const d of DATA.distributions) {
      const [first, second] = d.worst === "min" ? ["min", "median"] : ["median", "max"];
      for (const stat of [first, second]) {
        cols.push({ key: `${d.key}:${stat}`, label: withUnit(`${d.short} ${stat}`, d.unit), type: "number", format: d.digits,
          title: `${stat} of ${d.label} over the runs with a value (missing: ${d.missing})` });
      }
    }
    return cols;
  }

  function variantRows(columns) {
    return DATA.variants.map((v) => ({
      id: v.id,
      cells: columns.map((c) => {
        const [kind, name] = c.key.includes(":") ? [c.key.slice(0, c.key.indexOf(":")), c.key.slice(c.key.indexOf(":") + 1)] : [c.key, null];
        if (kind === "variant") return v.id;
        if (kind === "runs") return v.runs;
        if (kind === "param") return v.params[name];
        if (kind === "outcome") return v.counts[name] || 0;
        return v.stats[kind][name];
      }),
    }));
  }

  function variantsSection() {
    const columns = variantColumns();
    state.variantTable = new SortableTable("variants", columns, variantRows(columns), {
      onRowClick: selectVariant,
      selected: () => state.selected,
      onSort: drawCharts,
      missingTitle: "no run of this variant has a value",
    });
    return h("section", { id: "variants-section" },
      h("h2", {}, "Variants"),
      h("p", {}, "One row per variant. Click a column header to sort by it (again for the other " +
        "direction; numbers sort by value, text alphabetically, missing values last either way). " +
        "Click a row to show that variant below. The charts follow the table's order."),
      state.variantTable.element);
  }

  function chartsSection() {
    return h("section", { id: "charts" },
      h("h2", {}, "Outcomes"),
      h("p", {}, "Share of each variant's runs by outcome: " + DATA.outcomes.join(", ") +
        ". Hover a bar for its count; click a row to select the variant."),
      h("div", { id: "outcome-legend", class: "legend" },
        DATA.outcomes.map((o) => h("span", {}, h("span", { class: "swatch", style: `background:${outcomeColor(o)}` }), o))),
      h("div", { id: "outcome-chart" }),
      h("h2", {}, "Distributions"),
      h("p", {}, "Per variant: the box spans the quartiles, the dark line is the median, the " +
        "whiskers reach the smallest and the largest value. Only runs with a value count " +
        "(hover a box for the number of runs without one)."),
      h("div", { id: "box-plots", class: "grid" }),
      h("p", { id: "chart-limit", class: "table-note" }));
  }

  function drawCharts() {
    document.getElementById("outcome-chart").replaceChildren(outcomeChart());
    const boxes = document.getElementById("box-plots");
    boxes.replaceChildren(...DATA.distributions.map((d) => h("figure", { "data-key": d.key },
      h("figcaption", {}, withUnit(d.label, d.unit)),
      d.present ? boxPlot(d) : h("p", { class: "empty" }, "not in this dataset"))));
    const n = DATA.variants.length;
    document.getElementById("chart-limit").textContent = n > MAX_CHART_VARIANTS
      ? `The charts show the first ${MAX_CHART_VARIANTS} of ${n} variants in the table's order: sort the table to choose which.`
      : "";
  }

  function runColumns() {
    const cols = [
      { key: "seed", label: "seed", type: "number", format: "int", title: "seed of the run (crlbswarm simulate --seed)" },
      { key: "outcome", label: "outcome", type: "text", title: "outcome of the run", swatch: (v) => outcomeColor(v) },
    ];
    for (const m of DATA.metrics) cols.push({ key: m.key, label: withUnit(m.label, m.unit), type: "number", format: m.digits, title: `${m.key} (missing: ${m.missing})` });
    return cols;
  }

  function detailSection(variant) {
    const params = h("dl", { class: "spec" });
    for (const f of DATA.fields) {
      const v = variant.params[f];
      params.append(h("dt", {}, f), h("dd", {}, v === null ? DASH : String(v)));
    }
    const runs = variant.expected === null ? `${variant.runs} runs` : `${variant.runs} of ${variant.expected} runs`;
    const counts = h("ul", { class: "legend", id: "detail-outcomes" }, DATA.outcomes.map((o) =>
      h("li", { "data-outcome": o }, h("span", { class: "swatch", style: `background:${outcomeColor(o)}` }), `${o}: ${variant.counts[o] || 0}`)));
    const hists = h("div", { class: "grid hists" }, DATA.distributions.map((d) =>
      h("figure", { "data-key": d.key }, h("figcaption", {}, withUnit(d.label, d.unit)),
        d.present ? histogram(d, variant) : h("p", { class: "empty" }, "not in this dataset"))));
    let table;
    if (variant.rows) {
      const cols = runColumns();
      const rows = variant.rows.seed.map((seed, i) => ({
        id: seed,
        cells: cols.map((c) => c.key === "outcome" ? DATA.outcomes[variant.rows.outcome[i]] : variant.rows[c.key][i]),
      }));
      state.runTable = new SortableTable("runs", cols, rows, { limit: MAX_RUN_TABLE_ROWS, missingTitle: "no value for this run" });
      table = state.runTable.element;
    } else {
      state.runTable = null;
      table = h("p", { class: "table-note" }, `The per-run rows are not in this page: the campaign has ${DATA.total_runs} runs, ` +
        `more than the limit of ${DATA.max_run_rows} (crlbswarm report --max-run-rows). Read them from the Parquet dataset.`);
    }
    return h("section", { id: "detail", "data-variant": variant.id },
      h("h2", {}, `Variant ${variant.id}`),
      h("p", {}, `${runs}. Parameters:`), params, counts,
      h("h3", {}, "Distributions of this variant"),
      h("p", {}, "Bins are the same for every variant; the dashed line is the median."),
      hists,
      h("h3", {}, "Runs"),
      h("p", {}, "One row per run, sortable like the table of variants. Values are rounded to 6 " +
        "significant digits in this page; the dataset holds them in full."),
      table);
  }

  function selectVariant(id) {
    const variant = variantById(id);
    if (!variant) throw new Error(`no variant ${id}`);
    state.selected = id;
    document.getElementById("detail").replaceWith(detailSection(variant));
    state.variantTable.renderBody();
    drawCharts();
    return id;
  }

  function notesSection() {
    const items = DATA.distributions.map((d) => h("li", {}, `${d.label}: missing when ${d.missing}.`));
    return h("section", { id: "notes" },
      h("h2", {}, "Missing values (NaN, infinity, null)"),
      h("p", {}, "A quantity that does not exist for a run is stored as null in the Parquet " +
        "dataset (NaN and infinities are treated the same way). In this page such a value is " +
        `shown as ${DASH}, sorted last whichever the direction, and left out of the medians, ` +
        "quartiles, extremes, box plots and histograms, which say how many runs have a value. " +
        "A statistic of a variant with no value at all is itself missing."),
      h("ul", {}, items),
      h("h2", {}, "Outcomes of a run"),
      h("p", { id: "outcome-text" }, `The outcome of each run (crlbswarm.results): ${DATA.outcome_text}.`));
  }

  function build() {
    ROOT.replaceChildren(header(), sweepSection(), variantsSection(), chartsSection(),
      h("section", { id: "detail" }), notesSection());
    drawCharts();
    if (DATA.variants.length) selectVariant(DATA.variants[0].id);
  }

  build();

  window.crlbReport = {
    data: DATA,
    variants: DATA.variants,
    /** Keys of the variant table's columns, in order. */
    columns: () => state.variantTable.columns.map((c) => c.key),
    columnLabels: () => state.variantTable.columns.map((c) => c.label),
    /** Sort the variant table by a column (key, label or index), "asc" or "desc". */
    sortBy: (col, dir) => state.variantTable.sortBy(col, dir),
    sortState: () => state.variantTable.state(),
    /** The variant table's rows in their current order (values; null when missing). */
    tableRows: () => state.variantTable.currentRows(),
    /** Variant ids in the charts' order. */
    chartOrder: () => chartVariants().map((v) => v.id),
    select: (id) => selectVariant(id),
    selected: () => state.selected,
    runColumns: () => (state.runTable ? state.runTable.columns.map((c) => c.key) : []),
    sortRunsBy: (col, dir) => (state.runTable ? state.runTable.sortBy(col, dir) : null),
    runRows: () => (state.runTable ? state.runTable.currentRows() : []),
    ready: true,
  };
})();
