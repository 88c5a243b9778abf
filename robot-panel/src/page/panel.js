// The operator's panel: draws the machine from model.json once, then every state the
// server pushes (server-sent events on /events). Nothing is fetched from elsewhere.
"use strict";

const SVG = "http://www.w3.org/2000/svg";
const BUTTONS = ["START", "STOP", "RESET", "ACK", "HOME", "CONFIRM"];
const TRACK = 300;
let model = null;

function el(tag, attrs, text) {
  const e = tag.startsWith("svg:") ? document.createElementNS(SVG, tag.slice(4))
    : document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  return e;
}

function banner(text) {
  const b = document.getElementById("banner");
  b.hidden = !text;
  b.textContent = text || "";
}

function drawLanes() {
  const lanes = document.getElementById("lanes");
  for (const a of model.actuators) {
    const lane = el("div", { class: "lane actuator", "data-name": a.name, "data-position": "unknown" });
    lane.append(el("span", { class: "name" }, a.name));
    const svg = el("svg:svg", { width: TRACK + 30, height: 28 });
    svg.append(el("svg:rect", { class: "track", x: 10, y: 8, width: TRACK, height: 12, rx: 3 }));
    svg.append(el("svg:text", { class: "mark", x: 0, y: 27 }, "home"));
    svg.append(el("svg:text", { class: "mark", x: TRACK, y: 27 }, "end"));
    svg.append(el("svg:rect", { class: "rod", x: 10, y: 4, width: 20, height: 20, rx: 3 }));
    lane.append(svg);
    lane.append(el("span", { class: "info" }, ""));
    lanes.append(lane);
  }
}

function drawSteps() {
  const steps = document.getElementById("steps");
  model.sequence.forEach((s, i) => steps.append(el("li", { "data-index": i }, s)));
}

// A chart as its ECC: the states on a circle, the transitions as arrows, the current
// state lit.
function drawCharts() {
  const charts = document.getElementById("charts");
  model.charts.forEach((ch, ci) => {
    const n = ch.states.length;
    const r = Math.max(50, n * 13);
    const w = 2 * r + 110, h = 2 * r + 40;
    const box = el("div", { class: "chart", "data-chart": ci, "data-state": "" });
    box.append(el("h3", {}, ch.role + " / " + ch.name));
    const svg = el("svg:svg", { width: w, height: h });
    const defs = el("svg:defs");
    const marker = el("svg:marker", { id: "arrow", viewBox: "0 0 8 8", refX: 8, refY: 4,
      markerWidth: 6, markerHeight: 6, orient: "auto" });
    marker.append(el("svg:path", { d: "M0,0 L8,4 L0,8 z", fill: "#999" }));
    defs.append(marker);
    svg.append(defs);
    const at = (i) => {
      const t = 2 * Math.PI * i / n - Math.PI / 2;
      return [w / 2 + r * Math.cos(t), h / 2 + r * Math.sin(t)];
    };
    for (const [from, to, label] of ch.transitions) {
      const [x1, y1] = at(from), [x2, y2] = at(to);
      const len = Math.hypot(x2 - x1, y2 - y1) || 1;
      const k = Math.min(0.45, 14 / len);
      const line = el("svg:line", { x1: x1 + (x2 - x1) * k, y1: y1 + (y2 - y1) * k,
        x2: x2 - (x2 - x1) * k, y2: y2 - (y2 - y1) * k });
      line.append(el("svg:title", {}, label));
      svg.append(line);
    }
    ch.states.forEach((name, i) => {
      const [x, y] = at(i);
      const g = el("svg:g", { class: "state" + (i === ch.idle ? " idle" : ""), "data-index": i });
      const tw = Math.max(30, name.length * 6.2 + 8);
      g.append(el("svg:rect", { x: x - tw / 2, y: y - 9, width: tw, height: 18, rx: 4 }));
      g.append(el("svg:text", { x: x - tw / 2 + 4, y: y + 4 }, name));
      svg.append(g);
    });
    box.append(svg);
    charts.append(box);
  });
}

// A sorting station: a light per sensor (colour sensors, entry, bins), the ball at the
// sensors in its colour, each bin with the balls that landed in it.
function drawStation() {
  const st = model.station;
  if (!st) return;
  document.getElementById("station").hidden = false;
  const lights = document.getElementById("lights");
  for (const [name] of st.sensors.concat([st.entry], st.bins)) {
    const l = el("span", { class: "light" });
    l.append(el("i"), el("span", {}, name));
    lights.append(l);
  }
  const bins = document.getElementById("bins");
  st.bins.forEach(([name], i) => {
    const b = el("div", { class: "bin", "data-bin": i + 1 });
    b.append(el("h3", {}, "bin " + (i + 1) + " (" + name + "): 0"));
    bins.append(b);
  });
}

// Control functions: each one's places in a row, the one holding the token marked.
function drawFunctions() {
  if (!model.functions.length) return;
  document.getElementById("functions").hidden = false;
  const places = document.getElementById("places");
  for (const [name, ci] of model.functions) {
    const row = el("div", { class: "function", "data-function": name, "data-place": "" });
    row.append(el("b", {}, name));
    for (const p of model.charts[ci].states) row.append(el("span", { class: "place" }, p));
    places.append(row);
  }
}

function showFunctions(s) {
  document.querySelectorAll(".function").forEach((row, i) => {
    const st = s.charts[model.functions[i][1]];
    const names = model.charts[model.functions[i][1]].states;
    row.dataset.place = st === null ? "" : names[st] || "";
    row.querySelectorAll(".place").forEach((p, j) => p.classList.toggle("marked", j === st));
  });
}

function ball(colour) {
  const b = el("span", { class: "ball", title: colour, "data-colour": colour });
  b.style.background = colour === "unknown" ? "repeating-linear-gradient(45deg,#fff,#fff 3px,#c00 3px,#c00 6px)" : colour;
  return b;
}

function showStation(s) {
  const st = s.station;
  if (!st) return;
  document.querySelectorAll(".light").forEach((l, i) => l.classList.toggle("on", !!st.sensors[i]));
  const at = document.getElementById("at-sensors");
  at.replaceChildren(st.at_sensors ? ball(st.at_sensors) : "no ball");
  if (st.at_sensors) at.append(" " + st.at_sensors);
  document.getElementById("falling").textContent = st.falling;
  document.querySelectorAll(".bin").forEach((b, i) => {
    const balls = st.bins[i] || [];
    const h = b.querySelector("h3");
    h.textContent = "bin " + (i + 1) + " (" + model.station.bins[i][0] + "): " + balls.length;
    b.replaceChildren(h, ...balls.map(ball));
  });
}

function showLanes(s) {
  document.querySelectorAll(".lane").forEach((lane, i) => {
    const l = s.lanes[i], a = model.actuators[i];
    if (!l) return;
    lane.dataset.position = l.position;
    lane.dataset.late = l.late;
    const rod = lane.querySelector(".rod");
    const target = l.position === "end" || (l.position === "moving" && l.commanded === "+");
    const ms = l.commanded === "+" ? a.out_ms : a.back_ms;
    rod.style.transitionDuration = l.position === "moving" ? ms + "ms" : "0ms";
    rod.style.transform = "translateX(" + (target ? TRACK - 20 : 0) + "px)";
    const last = l.last_ms === null ? "no travel yet"
      : "last " + a.name + l.last_dir + " " + l.last_ms + " ms";
    const plant = a.out_ms + " / " + a.back_ms + " ms";
    const dog = model.watchdog_ms ? ", watchdog " + model.watchdog_ms + " ms" : "";
    lane.querySelector(".info").textContent = l.position.padEnd(8) + last +
      " (plant " + plant + dog + ")" + (l.late ? " LATE" : "");
  });
}

function showCycle(s) {
  document.querySelectorAll("#steps li").forEach((li, i) => {
    li.className = s.step === null ? "" : i < s.step ? "done" : i === s.step ? "current" : "";
  });
  document.getElementById("cycles").textContent = s.cycles;
  document.getElementById("cycle-ms").textContent =
    s.cycle_ms.length ? s.cycle_ms.map((t) => t + " ms").join(", ") : "none yet";
}

function showCharts(s) {
  document.querySelectorAll(".chart").forEach((box, i) => {
    const st = s.charts[i];
    box.dataset.state = st === null ? "" : model.charts[i].states[st] || "";
    box.querySelectorAll(".state").forEach((g) => {
      g.classList.toggle("current", Number(g.dataset.index) === st);
    });
  });
}

function showNodes(s) {
  const body = document.querySelector("#nodes tbody");
  body.replaceChildren();
  for (const n of s.nodes) {
    const tr = el("tr", { class: n.answering ? "node" : "node silent", "data-role": n.role });
    const state = n.answering ? n.standing || "?"
      : "NOT ANSWERING" + (n.silent_since ? " since " + n.silent_since + " UTC" : "");
    const gen = n.generation === null ? "" : n.generation +
      (n.staged ? " (staged " + n.staged + ")" : "") + (n.trial ? " on trial" : "");
    const sec = n.security;
    const drops = !sec ? "" : !sec.keyed ? "security off" :
      ["not_secured", "bad_mic", "replayed", "unknown_key", "wrong_level", "malformed",
        "table_full"].map((k) => k.replace("_", " ") + " " + sec[k]).join(", ");
    for (const v of [n.role, n.addr, state, gen, n.sent ?? "", n.retries ?? "",
      n.link_alarms ? "0b" + n.link_alarms.toString(2) : n.link_alarms ?? "",
      n.alarms_latched, drops]) {
      tr.append(el("td", {}, String(v)));
    }
    body.append(tr);
  }
}

function showAlarms(s) {
  const body = document.querySelector("#alarms tbody");
  body.replaceChildren();
  for (const a of s.alarms) {
    const tr = el("tr", { class: "alarm", "data-level": a.level, "data-latched": a.latched });
    for (const v of [a.level, a.time, a.node + " " + a.role, a.source, a.state]) {
      tr.append(el("td", {}, v));
    }
    body.append(tr);
  }
  document.getElementById("no-alarms").hidden = s.alarms.length > 0;
}

function showButtons(s) {
  for (const name of BUTTONS) {
    const b = document.getElementById(name), st = s.buttons[name];
    b.disabled = !st.enabled;
    b.title = st.enabled ? "" : st.why;
  }
  document.getElementById("said").textContent = s.busy ? s.busy + "..." : s.said || "";
}

function showEvents(s) {
  document.getElementById("event-count").textContent = s.event_count;
  document.getElementById("events").replaceChildren(...s.events.map((e) =>
    el("li", {}, e.at + " s  " + e.role + ": " + e.event)));
}

function show(s) {
  const m = document.getElementById("medium");
  m.textContent = s.medium_ok ? "medium ok" : "medium: " + s.medium;
  m.className = s.medium_ok ? "ok" : "bad";
  const silent = s.nodes.filter((n) => !n.answering).map((n) => n.role + " (" + n.addr + ")");
  banner(!s.medium_ok ? "The medium is gone: " + s.medium + ". Nothing can be commanded."
    : silent.length ? "Not answering: " + silent.join(", ") : "");
  showLanes(s); showStation(s); showFunctions(s); showCycle(s); showCharts(s); showNodes(s); showAlarms(s); showEvents(s); showButtons(s);
  document.body.dataset.version = Number(document.body.dataset.version || 0) + 1;
}

async function press(name) {
  const b = document.getElementById(name);
  b.disabled = true;
  // The header no page of another origin may send: the panel takes buttons with it only.
  const r = await fetch("command/" + name, { method: "POST", headers: { "X-Panel": "button" } });
  document.getElementById("said").textContent = await r.text();
}

function listen() {
  const link = document.getElementById("link");
  const events = new EventSource("events");
  events.onopen = () => { link.textContent = "live"; link.className = "ok"; };
  events.onmessage = (e) => show(JSON.parse(e.data));
  events.onerror = () => {
    link.textContent = "no connection to the panel";
    link.className = "bad";
    for (const name of BUTTONS) document.getElementById(name).disabled = true;
  };
}

async function main() {
  model = await (await fetch("model.json")).json();
  document.getElementById("name").textContent = model.name;
  document.title = model.name + " panel";
  drawSteps(); drawStation(); drawFunctions(); drawLanes(); drawCharts();
  for (const name of BUTTONS) document.getElementById(name).onclick = () => press(name);
  listen();
}

main();
