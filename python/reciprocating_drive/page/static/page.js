// The twin's live page (docs/page.md): the state from /api/state, trends from /api/trend, then
// server-sent events from /stream with each new revolution, card, alarm and health change.
"use strict";

const S = { meta: null, limits: {}, origin: null, trend: null, charts: {}, cards: [], alarms: [] };

function fmt(v, digits = 5) {
  if (v === null || v === undefined) return "—";
  const a = Math.abs(v);
  if (a !== 0 && (a >= 1e6 || a < 1e-3)) return v.toExponential(digits - 1);
  return Number(v.toPrecision(digits)).toString();
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

function buildValues() {
  const now = document.getElementById("now");
  now.replaceChildren();
  for (const v of S.meta) {
    const box = el("div", { class: "value", id: "v-" + v.key });
    box.append(el("div", { class: "name" }, v.label));
    const num = el("span", { class: "num", "data-key": v.key }, "—");
    box.append(num, el("span", { class: "unit" }, " " + v.unit));
    const lim = S.limits[v.key] || {};
    const parts = [];
    if (lim.low !== null && lim.low !== undefined) parts.push("low " + fmt(lim.low));
    if (lim.high !== null && lim.high !== undefined) parts.push("high " + fmt(lim.high));
    box.append(el("div", { class: "lim" }, parts.length ? "limits: " + parts.join(", ") : "no limits"));
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
    num.textContent = fmt(x);
    // The exact number (JavaScript writes the shortest string that reads back to the same double).
    num.dataset.value = x === null ? "" : String(x);
    const lim = S.limits[v.key] || {};
    const beyond = x !== null && ((lim.high !== null && lim.high !== undefined && x > lim.high) ||
                                  (lim.low !== null && lim.low !== undefined && x < lim.low));
    box.classList.toggle("beyond", beyond);
  }
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
  g.fillText(fmt(y1, 3) + " N", 2, m.t + 10);
  g.fillText(fmt(y0, 3) + " N", 2, m.t + H);
  g.fillText(fmt(x0, 3) + " m", m.l, c.height - 8);
  g.fillText(fmt(x1, 3) + " m", m.l + W - 50, c.height - 8);
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
  const t = document.getElementById("health");
  t.replaceChildren();
  const conn = h.connected === null ? "—" : h.connected ? "connected" : "NOT connected";
  const rows = [
    ["source", conn, "connected"],
    ["lag (now − sample time)", h.lag === null ? "—" : fmt(h.lag, 3) + " s", "lag"],
    ["gaps", String(h.gaps), "gaps"],
    ["dropped samples", String(h.dropped), "dropped"],
    ["FMU errors", String(h.fmu_errors), "fmu_errors"],
    ["last sample", h.last_sample_time === null ? "—" : when(h.last_sample_time), "last_sample"],
    ["run", h.run_status === null ? "—" : h.run_status, "run_status"],
    ["last event", h.last_event ? h.last_event.kind + ": " + h.last_event.message : "—", "last_event"],
  ];
  for (const [name, val, key] of rows) {
    const tr = el("tr", { "data-key": key });
    tr.append(el("td", {}, name), el("td", {}, val));
    t.append(tr);
  }
}

function showAlarms(list) {
  const body = document.querySelector("#alarms tbody");
  body.replaceChildren();
  for (const a of [...list].reverse()) {
    const tr = el("tr", { class: a.cleared === null ? "active" : "", "data-name": a.name,
                          "data-state": a.cleared === null ? "raised" : "cleared", title: a.message });
    tr.append(el("td", {}, a.name), el("td", {}, a.severity), el("td", {}, when(a.raised, a.raised_wall)),
              el("td", {}, a.cleared === null ? "active" : when(a.cleared, a.cleared_wall)));
    body.append(tr);
  }
}

function xs() {
  return S.trend.t.map((t) => (S.origin !== null ? S.origin + t : t));
}

function buildTrends() {
  const box = document.getElementById("trends");
  for (const c of Object.values(S.charts)) c.destroy();
  S.charts = {};
  box.replaceChildren();
  const x = xs();
  for (const v of S.meta) {
    const div = el("div", { class: "trend", id: "t-" + v.key });
    box.append(div);
    const lim = S.limits[v.key] || {};
    const series = [{ label: S.origin !== null ? "time" : "t [s]" },
                    { label: v.label + " [" + v.unit + "]", stroke: "#1f3a5f", width: 1.5 }];
    const data = [x, S.trend[v.key]];
    for (const side of ["high", "low"]) {
      if (lim[side] !== null && lim[side] !== undefined) {
        series.push({ label: side + " limit", stroke: "#c62828", dash: [6, 4], width: 1 });
        data.push(x.map(() => lim[side]));
      }
    }
    const opts = {
      width: 440, height: 170, series,
      scales: { x: { time: S.origin !== null } },
      axes: [{ label: S.origin !== null ? "" : "twin time [s]" }, { size: 70 }],
      cursor: { drag: { x: true, y: false }, sync: { key: "trends" } },
      legend: { live: true },
    };
    S.charts[v.key] = new uPlot(opts, data, div);
  }
  document.getElementById("trends").dataset.points = S.trend.t.length;
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
  const x = xs();
  for (const v of S.meta) {
    const c = S.charts[v.key];
    if (!c) continue;
    const data = [x, S.trend[v.key]];
    const lim = S.limits[v.key] || {};
    for (const side of ["high", "low"]) if (lim[side] !== null && lim[side] !== undefined) data.push(x.map(() => lim[side]));
    c.setData(data, true);
  }
  document.getElementById("trends").dataset.points = S.trend.t.length;
}

async function loadTrend() {
  const w = document.getElementById("window").value;
  const r = await fetch("/api/trend?window=" + encodeURIComponent(w), { credentials: "same-origin" });
  if (!r.ok) { document.getElementById("trend-source").textContent = await r.text(); return; }
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
  const opened = new Promise((resolve) => {
    const es = new EventSource("/stream");
    es.onopen = () => { badge.textContent = "live"; badge.className = "badge ok"; resolve(); };
    es.onerror = () => { badge.textContent = "reconnecting"; badge.className = "badge bad"; };
    es.onmessage = (ev) => { if (live) apply(JSON.parse(ev.data)); else held.push(ev.data); };
  });
  let lastRev = -1;
  function apply(m) {
    if (m.revs && m.revs.length) {
      const revs = m.revs.filter((r) => r.revolution > lastRev);
      if (revs.length) {
        lastRev = revs[revs.length - 1].revolution;
        showLast(revs[revs.length - 1]);
        appendTrend(revs);
      }
    }
    if (m.card) { S.cards.push(m.card); while (S.cards.length > 6) S.cards.shift(); drawCards(); }
    if (m.health) showHealth(m.health);
    if (m.alarms) showAlarms(m.alarms);
  }
  await opened;
  const r = await fetch("/api/state", { credentials: "same-origin" });
  const st = await r.json();
  S.meta = st.values; S.limits = st.limits; S.origin = st.time_origin;
  S.cards = st.cards; S.alarms = st.alarms;
  if (st.last) lastRev = st.last.revolution;
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
