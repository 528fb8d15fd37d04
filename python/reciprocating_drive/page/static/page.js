// The twin's live page (docs/page.md): the state from /api/state, trends from /api/trend, then
// server-sent events from /stream with each new revolution, card, alarm and health change.
"use strict";

const S = { meta: null, limits: {}, origin: null, trend: null, charts: {}, scales: {}, cards: [],
            alarms: [], last: null, health: null };

function fmt(v, digits = 5) {
  if (v === null || v === undefined) return "—";
  const a = Math.abs(v);
  if (a !== 0 && (a >= 1e6 || a < 1e-3)) return v.toExponential(digits - 1);
  return Number(v.toPrecision(digits)).toString();
}

// Units as an operator reads them: an SI prefix chosen by the size of the numbers (kN, MPa, mm,
// µm), percent for a ratio the server marks "%". `scaleOf` gives the divisor and the unit shown.
const PREFIXES = [[1e9, "G"], [1e6, "M"], [1e3, "k"], [1, ""], [1e-3, "m"], [1e-6, "µ"], [1e-9, "n"]];
const PREFIXED = new Set(["N", "N·m", "J", "Pa", "m"]);
function scaleOf(unit, size) {
  if (unit === "%") return { k: 0.01, unit: "%" };
  if (!PREFIXED.has(unit) || !Number.isFinite(size) || size === 0) return { k: 1, unit };
  // Metres stay metres from 1 mm to 1 km (a stroke of 0.4 m reads as such).
  if (unit === "m" && size >= 1e-3 && size < 1e3) return { k: 1, unit };
  for (const [f, p] of PREFIXES) if (size >= f * 0.9995) return { k: f, unit: p + unit };
  return { k: 1e-9, unit: "n" + unit };
}

function withUnit(v, unit, digits = 5) {
  // One number with its unit, e.g. "3.5176 kN", "5.2 %".
  if (v === null || v === undefined) return "—";
  const s = scaleOf(unit, Math.abs(v));
  return fmt(v / s.k, digits) + " " + s.unit;
}

// The y-range of a trend (docs/page.md, "Trends"; the static plots use the same rule,
// plots.y_range): the data's range, with each limit that lies within half the value's size of
// it, widened to a minimum span of MIN_SPAN times the largest magnitude among them, so that
// rounding noise of a steady value is drawn as the flat line it is.
const MIN_SPAN = 0.02, NEAR = 0.5;
function yRange(values, limits) {
  let lo = Infinity, hi = -Infinity;
  for (const v of values) if (v !== null && Number.isFinite(v)) { if (v < lo) lo = v; if (v > hi) hi = v; }
  const lims = limits.filter((x) => x !== null && x !== undefined && Number.isFinite(x));
  if (lo > hi) {
    if (!lims.length) return { lo: 0, hi: 1, shown: [] };
    lo = Math.min(...lims); hi = Math.max(...lims);
  }
  const size = Math.max(Math.abs(lo), Math.abs(hi));
  const shown = lims.filter((x) => Math.abs(x - Math.min(Math.max(x, lo), hi)) <= NEAR * size);
  for (const x of shown) { lo = Math.min(lo, x); hi = Math.max(hi, x); }
  const span = MIN_SPAN * Math.max(size, ...shown.map(Math.abs)) || 1;
  if (hi - lo < span) { const mid = 0.5 * (lo + hi); lo = mid - span / 2; hi = mid + span / 2; }
  const pad = 0.05 * (hi - lo);
  return { lo: lo - pad, hi: hi + pad, shown };
}

function tickLabels(splits, incr, k) {
  // As many decimals as the tick step needs, more if two labels would still read the same.
  const step = Math.abs(incr / k);
  let d = 0;
  while (d < 12 && Math.abs(step * 10 ** d - Math.round(step * 10 ** d)) > 1e-6 * step * 10 ** d) d++;
  for (; d <= 12; d++) {
    const out = splits.map((v) => (v / k).toFixed(d).replace(/^-(0\.?0*)$/, "$1"));
    if (new Set(out).size === out.length) return out;
  }
  return splits.map((v) => String(v / k));
}

function when(t, wall) {
  // Twin time t [s] as a clock time when the source has a clock, else "t = ... s".
  if (t === null || t === undefined) return "—";
  if (S.origin !== null) return new Date((S.origin + t) * 1000).toLocaleString();
  const w = wall ? " (" + new Date(wall * 1000).toLocaleTimeString() + ")" : "";
  return "t = " + fmt(t, 6) + " s" + w;
}

function el(tag, attrs = {}, text) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

function limitText(v) {
  const lim = S.limits[v.key] || {};
  const parts = [];
  if (lim.low !== null && lim.low !== undefined) parts.push("low " + withUnit(lim.low, v.unit));
  if (lim.high !== null && lim.high !== undefined) parts.push("high " + withUnit(lim.high, v.unit));
  return parts.length ? "limits: " + parts.join(", ") : "no limits";
}

function buildValues() {
  const now = document.getElementById("now");
  now.replaceChildren();
  for (const v of S.meta) {
    const box = el("div", { class: "value", id: "v-" + v.key });
    box.append(el("div", { class: "name" }, v.label));
    const num = el("span", { class: "num", "data-key": v.key }, "—");
    box.append(num, el("span", { class: "unit" }, " " + v.unit));
    box.append(el("div", { class: "lim" }, limitText(v)));
    now.append(box);
  }
}

function showLast(r) {
  if (!r) return;
  const label = document.getElementById("rev-label");
  label.textContent = "revolution " + r.revolution + " at " + when(r.t);
  label.dataset.revolution = r.revolution;
  for (const v of S.meta) {
    const box = document.getElementById("v-" + v.key);
    const num = box.querySelector(".num");
    const x = r[v.key];
    const sc = scaleOf(v.unit, x === null ? NaN : Math.abs(x));
    num.textContent = x === null || x === undefined ? "—" : fmt(x / sc.k);
    box.querySelector(".unit").textContent = " " + sc.unit;
    // The exact number in SI (JavaScript writes the shortest string that reads back to the same
    // double), whatever the unit shown.
    num.dataset.value = x === null || x === undefined ? "" : String(x);
    const lim = S.limits[v.key] || {};
    const beyond = x !== null && ((lim.high !== null && lim.high !== undefined && x > lim.high) ||
                                  (lim.low !== null && lim.low !== undefined && x < lim.low));
    box.classList.toggle("beyond", beyond);
  }
}

function axisText(v, span, unit) {
  // A card axis end: decimals for a thousandth of the axis' span, so 2.75e-7 m on a 0.4 m axis
  // reads as 0.
  const d = Math.max(0, Math.min(9, 2 - Math.floor(Math.log10(span || 1))));
  return String(Number(v.toFixed(d)) || 0) + " " + unit;
}

function drawCards() {
  const c = document.getElementById("card");
  const g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  if (!S.cards.length) return;
  let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
  for (const k of S.cards) {
    for (const x of k.x) { if (x < x0) x0 = x; if (x > x1) x1 = x; }
    for (const y of k.y) { if (y < y0) y0 = y; if (y > y1) y1 = y; }
  }
  if (x1 === x0) x1 = x0 + 1;
  if (y1 === y0) y1 = y0 + 1;
  const m = { l: 60, r: 10, t: 10, b: 30 };
  const W = c.width - m.l - m.r, H = c.height - m.t - m.b;
  const px = (x) => m.l + (x - x0) / (x1 - x0) * W;
  const py = (y) => m.t + (1 - (y - y0) / (y1 - y0)) * H;
  g.strokeStyle = "#999"; g.lineWidth = 1;
  g.strokeRect(m.l, m.t, W, H);
  g.fillStyle = "#555"; g.font = "11px sans-serif";
  const fy = scaleOf("N", Math.max(Math.abs(y0), Math.abs(y1)));
  const fx = scaleOf("m", Math.max(Math.abs(x0), Math.abs(x1)));
  const ylab = [axisText(y1 / fy.k, (y1 - y0) / fy.k, fy.unit), axisText(y0 / fy.k, (y1 - y0) / fy.k, fy.unit)];
  const xlab = [axisText(x0 / fx.k, (x1 - x0) / fx.k, fx.unit), axisText(x1 / fx.k, (x1 - x0) / fx.k, fx.unit)];
  g.fillText(ylab[0], 2, m.t + 10);
  g.fillText(ylab[1], 2, m.t + H);
  g.fillText(xlab[0], m.l, c.height - 8);
  g.fillText(xlab[1], m.l + W - 50, c.height - 8);
  c.dataset.axis = JSON.stringify({ x: xlab, y: ylab });
  S.cards.forEach((k, i) => {
    const last = i === S.cards.length - 1;
    g.strokeStyle = last ? "#000" : "rgba(120,120,120,0.5)";
    g.lineWidth = last ? 2 : 1;
    g.beginPath();
    k.x.forEach((x, j) => (j ? g.lineTo(px(x), py(k.y[j])) : g.moveTo(px(x), py(k.y[j]))));
    g.stroke();
  });
  c.dataset.cards = S.cards.length;
  c.dataset.lastIndex = S.cards[S.cards.length - 1].index;
}

function showHealth(h) {
  S.health = h;
  const t = document.getElementById("health");
  t.replaceChildren();
  const ended = h.ended;
  const status = h.run_status || "running";
  const conn = ended ? "closed: the run " + status
    : h.connected === null ? "not watched (the page follows a database)"
    : h.connected ? "connected" : "NOT connected";
  let lag;
  if (S.origin === null) lag = "none: a file replay has no clock";
  else if (ended) lag = "none: the run " + status;
  else if (h.lag === null) lag = "no sample yet";
  else lag = fmt(h.lag, 3) + " s";
  const run = status + (h.run_message ? ": " + h.run_message : "");
  // The machine's state (docs/twin.md "Machine states"): running, stopped since, reversing since.
  const machineText = (m) => !m ? "running (no stop seen yet)"
    : m.state === "running" ? "running" + (m.since === null ? "" : " since " + when(m.since))
    : m.state + (m.since === null ? "" : " since " + when(m.since));
  const ev = h.last_event;
  const last = !ev ? "none yet" : ev.message.startsWith(ev.kind + ":") ? ev.message : ev.kind + ": " + ev.message;
  const rows = [
    ["source", conn, "connected", !ended && h.connected === false],
    ["lag (now − sample time)", lag, "lag", false],
    ["gaps", String(h.gaps), "gaps", false],
    ["dropped samples", String(h.dropped), "dropped", false],
    ["FMU errors", String(h.fmu_errors), "fmu_errors", h.fmu_errors > 0],
    ["last sample", h.last_sample_time === null ? "none yet" : when(h.last_sample_time), "last_sample", false],
    ["run", run, "run_status", status === "failed"],
    ["last event", last, "last_event", false],
    ["machine", machineText(h.machine), "machine", false],
  ];
  for (const [name, val, key, bad] of rows) {
    const tr = el("tr", { "data-key": key, class: bad ? "bad" : "" });
    tr.append(el("td", {}, name), el("td", {}, val));
    t.append(tr);
  }
}

function showAlarms(list) {
  const body = document.querySelector("#alarms tbody");
  body.replaceChildren();
  for (const a of [...list].reverse()) {
    const tr = el("tr", { class: a.cleared === null ? "active" : "", "data-name": a.name,
                          "data-state": a.cleared === null ? "raised" : "cleared", title: a.message,
                          "data-raised": String(a.raised), "data-cleared": String(a.cleared) });
    tr.append(el("td", {}, a.name), el("td", {}, a.severity), el("td", {}, when(a.raised, a.raised_wall)),
              el("td", {}, a.cleared === null ? "active" : when(a.cleared, a.cleared_wall)));
    body.append(tr);
  }
}

function xs() {
  return S.trend.t.map((t) => (S.origin !== null ? S.origin + t : t));
}

function limitsOf(key) {
  const lim = S.limits[key] || {};
  return ["high", "low"].filter((side) => lim[side] !== null && lim[side] !== undefined)
    .map((side) => [side, lim[side]]);
}

function trendScale(v) {
  // One prefix for the whole axis, from the largest magnitude of its data and limits shown.
  const vals = S.trend[v.key].filter((x) => x !== null && Number.isFinite(x));
  const r = yRange(vals, limitsOf(v.key).map(([, x]) => x));
  const size = Math.max(0, ...vals.map(Math.abs), ...r.shown.map(Math.abs));
  return scaleOf(v.unit, size);
}

function trendNote(v) {
  // Limits outside the chart's range are named in its title instead of flattening the data.
  const vals = S.trend[v.key].filter((x) => x !== null && Number.isFinite(x));
  const r = yRange(vals, limitsOf(v.key).map(([, x]) => x));
  const off = limitsOf(v.key).filter(([, x]) => !r.shown.includes(x));
  return off.map(([side, x]) => side + " limit " + withUnit(x, v.unit) + (x > r.hi ? " above" : " below")).join(", ");
}

function buildTrends() {
  const box = document.getElementById("trends");
  for (const c of Object.values(S.charts)) c.destroy();
  S.charts = {};
  S.scales = {};
  box.replaceChildren();
  const x = xs();
  const clock = S.origin !== null;
  for (const v of S.meta) {
    const div = el("div", { class: "trend", id: "t-" + v.key });
    const sc = trendScale(v);
    S.scales[v.key] = sc.unit;
    const title = el("h3", { class: "trend-title" }, v.label + " [" + sc.unit + "]");
    const note = trendNote(v);
    if (note) title.append(el("span", { class: "note" }, " (" + note + ")"));
    div.append(title);
    box.append(div);
    const series = [{ label: clock ? "time" : "t [s]" },
                    { label: v.label, stroke: "#1f3a5f", width: 1.5,
                      value: (u, y) => (y === null || y === undefined ? "—" : fmt(y / sc.k) + " " + sc.unit) }];
    const data = [x, S.trend[v.key]];
    for (const [side, lv] of limitsOf(v.key)) {
      series.push({ label: side + " limit", stroke: "#c62828", dash: [6, 4], width: 1,
                    value: () => withUnit(lv, v.unit) });
      data.push(x.map(() => lv));
    }
    const opts = {
      width: 440, height: 200, series,
      scales: {
        x: { time: clock },
        y: { range: () => {
          const r = yRange(S.trend[v.key], limitsOf(v.key).map(([, l]) => l));
          return [r.lo, r.hi];
        } },
      },
      axes: [{ label: clock ? "clock time" : "twin time [s] (file replay)" },
             { size: 70, space: 24,
               values: (u, splits, ai, space, incr) => tickLabels(splits, incr, sc.k) }],
      cursor: { drag: { x: true, y: false }, sync: { key: "trends" } },
      legend: { live: true },
    };
    S.charts[v.key] = new uPlot(opts, data, div);
  }
  box.dataset.points = S.trend.t.length;
  box.dataset.clock = clock ? "1" : "0";
}

function appendTrend(revs) {
  if (!S.trend) return;
  for (const r of revs) {
    if (r.t === null) continue;
    S.trend.t.push(r.t);
    for (const v of S.meta) S.trend[v.key].push(r[v.key]);
  }
  // Keep the selected window (in twin time) behind the newest revolution.
  const w = Number(document.getElementById("window").value);
  const tEnd = S.trend.t[S.trend.t.length - 1];
  let cut = 0;
  while (cut < S.trend.t.length && S.trend.t[cut] < tEnd - w) cut++;
  if (cut) for (const k of Object.keys(S.trend)) if (Array.isArray(S.trend[k])) S.trend[k].splice(0, cut);
  // A new prefix (kN·m instead of N·m) or a limit now in or out of range: the charts are redrawn.
  if (S.meta.some((v) => trendScale(v).unit !== S.scales[v.key] ||
                         (trendNote(v) !== "") !== (document.querySelector("#t-" + v.key + " .trend-title .note") !== null))) {
    buildTrends();
    return;
  }
  const x = xs();
  for (const v of S.meta) {
    const c = S.charts[v.key];
    if (!c) continue;
    const data = [x, S.trend[v.key]];
    for (const [, lv] of limitsOf(v.key)) data.push(x.map(() => lv));
    c.setData(data, true);
  }
  document.getElementById("trends").dataset.points = S.trend.t.length;
}

async function loadTrend() {
  const w = document.getElementById("window").value;
  const r = await fetch("/api/trend?window=" + encodeURIComponent(w), { credentials: "same-origin" });
  if (!r.ok) {
    // A database the twin has not yet written its run into (the page starts first): the reason
    // is shown and the trends are asked for again.
    document.getElementById("trend-source").textContent = await r.text();
    if (!S.trend && !S.retry) S.retry = setTimeout(() => { S.retry = null; loadTrend(); }, 1000);
    return;
  }
  S.trend = await r.json();
  document.getElementById("trend-source").textContent = "from the " + S.trend.source;
  buildTrends();
}

async function main() {
  // The stream first, its messages held until the state is drawn: an update flushed between the
  // state's fetch and the stream's start is then not lost (revolutions already in the state are
  // skipped, health and alarms are whole snapshots).
  const badge = document.getElementById("stream");
  const held = [];
  let live = false;
  let closed = false;
  const opened = new Promise((resolve) => {
    const es = new EventSource("/stream");
    es.onopen = () => { badge.textContent = "live"; badge.className = "badge ok"; resolve(); };
    es.onerror = () => {
      if (closed) return;
      badge.textContent = "reconnecting"; badge.className = "badge bad";
    };
    es.onmessage = (ev) => {
      const m = JSON.parse(ev.data);
      if (m.closed) {
        // The twin stopped its page (the run is over): no reconnecting, the last state stays.
        closed = true;
        es.close();
        badge.textContent = "stopped: page no longer updated"; badge.className = "badge ended";
        return;
      }
      if (live) apply(m); else held.push(ev.data);
    };
  });
  let lastRev = -1;
  function apply(m) {
    if (m.revs && m.revs.length) {
      const revs = m.revs.filter((r) => r.revolution > lastRev);
      if (revs.length) {
        lastRev = revs[revs.length - 1].revolution;
        S.last = revs[revs.length - 1];
        showLast(S.last);
        appendTrend(revs);
      }
    }
    if (m.card) { S.cards.push(m.card); while (S.cards.length > 6) S.cards.shift(); drawCards(); }
    if (m.origin !== undefined && m.origin !== S.origin) {
      // The source's clock became known (an OPC UA source: its first sample): clock times.
      S.origin = m.origin;
      if (S.trend) buildTrends();
      showAlarms(S.alarms);
      if (S.last) showLast(S.last);
    }
    if (m.values) {
      // The machine's rod became known: the values it has, under their names.
      S.meta = m.values;
      buildValues();
      if (S.trend) buildTrends();
      if (S.last) showLast(S.last);
    }
    if (m.health) showHealth(m.health);
    if (m.alarms) { S.alarms = m.alarms; showAlarms(m.alarms); }
  }
  await opened;
  const r = await fetch("/api/state", { credentials: "same-origin" });
  const st = await r.json();
  S.meta = st.values; S.limits = st.limits; S.origin = st.time_origin;
  S.cards = st.cards; S.alarms = st.alarms;
  if (st.last) lastRev = st.last.revolution;
  S.last = st.last;
  buildValues();
  showLast(st.last);
  drawCards();
  showHealth(st.health);
  showAlarms(st.alarms);
  await loadTrend();
  document.getElementById("window").addEventListener("change", loadTrend);
  live = true;
  for (const d of held.splice(0)) apply(JSON.parse(d));
  document.body.dataset.ready = "1";
}

main();
