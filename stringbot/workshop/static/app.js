// The workshop page: forms that run stringbot's commands, and the live windings (server-sent events).
"use strict";

const $ = (sel, root = document) => root.querySelector(sel);
const state = {machines: [], plans: [], plansVersion: -1, live: null, drawings: {}, cards: {}};

async function api(path, body, {form = false} = {}) {
  const opts = body === undefined ? {} : {method: "POST"};
  if (body !== undefined) {
    if (form) opts.body = body;
    else { opts.body = JSON.stringify(body); opts.headers = {"Content-Type": "application/json"}; }
  }
  const resp = await fetch(path, opts);
  const data = await resp.json().catch(() => ({error: `the server answered ${resp.status}`}));
  if (!resp.ok) throw new Error(data.error || `the server answered ${resp.status}`);
  return data;
}

function show(el, text, kind) {
  el.textContent = "";
  el.className = "result " + (kind || "");
  if (Array.isArray(text)) text.forEach(line => { const d = document.createElement("div"); d.textContent = line; el.appendChild(d); });
  else el.textContent = text || "";
}

function fmt(seconds) {
  if (seconds === null || seconds === undefined) return "–";
  seconds = Math.max(0, Math.round(seconds));
  const h = Math.floor(seconds / 3600), m = Math.floor((seconds % 3600) / 60), s = seconds % 60;
  return h ? `${h}:${String(m).padStart(2, "0")}:${String(s).padStart(2, "0")}` : `${m}:${String(s).padStart(2, "0")}`;
}

function swatch(color) {
  const s = document.createElement("span");
  s.className = "swatch";
  s.style.background = color;
  s.title = color;
  return s;
}

function debounce(fn, ms) {
  let t = null;
  return (...args) => { clearTimeout(t); t = setTimeout(() => fn(...args), ms); };
}

// ---- the forms' command lines ----------------------------------------------------------------
function planFields() {
  const f = $("#plan-form"), file = $("#picture").files[0];
  return {action: "plan", picture: file ? file.name : $("#picture-name").value, name: f.name.value,
          machine: f.machine.value, pins: f.pins.value, lines: f.lines.value, colors: f.colors.value,
          spool_changes: f.spool_changes.value, face: f.face.value, fit: f.fit.checked, force: f.force.checked};
}

function windFields() {
  const f = $("#wind-form");
  return {plan: f.plan.value, machine: f.machine.value, target: f.target.value, port: f.port.value,
          faults: f.faults.value, realtime: f.realtime.checked};
}

const planCli = debounce(async () => {
  try { $("#plan-cli").textContent = (await api("/api/command", planFields())).command; }
  catch (e) { $("#plan-cli").textContent = e.message; }
}, 150);

const windCli = debounce(async () => {
  const fields = windFields();
  const simulator = fields.target !== "port";
  $("#faults-label").hidden = !simulator;
  $("#realtime-label").hidden = !simulator;
  if (!fields.plan) { $("#wind-cli").textContent = "plan a picture first"; return; }
  try {
    $("#wind-cli").textContent = (await api("/api/command", {action: "wind", ...fields})).command;
    const journal = journalOf(fields);
    const resumable = journal && journal.resumable && journal.machine === fields.machine;
    $("#resume-button").disabled = !resumable;
    $("#resume-cli-row").hidden = !resumable;
    if (resumable) $("#resume-cli").textContent = (await api("/api/command", {action: "resume", ...fields})).command;
    showJournal(journal);
  } catch (e) { $("#wind-cli").textContent = e.message; }
}, 150);

function journalOf(fields) {
  const plan = state.plans.find(p => p.name === fields.plan);
  return plan ? plan.journals[fields.target] : null;
}

function showJournal(j) {
  const el = $("#wind-journal");
  if (!j) { el.textContent = ""; return; }
  let text = `journal ${j.path}: ` + (j.finished ? `finished, all ${j.total} steps` : `${j.done} of ${j.total} steps done`);
  if (j.stop) text += `; stopped at step ${j.stop.step} (pin ${j.stop.pin}): ${j.stop.reason}` + (j.stop.error ? ` — ${j.stop.error}` : "");
  if (j.resumable) text += ". Resume continues exactly.";
  el.textContent = text;
}

// ---- plans ---------------------------------------------------------------------------------------
async function loadPlans() {
  const data = await api("/api/plans");
  state.plans = data.plans;
  $("#folder").textContent = data.folder;
  $("#plans-count").textContent = data.plans.length ? `${data.plans.length} in the folder` : "";
  const pics = $("#picture-name"), keep = pics.value;
  pics.innerHTML = '<option value="">—</option>';
  data.pictures.forEach(n => pics.add(new Option(n, n)));
  pics.value = data.pictures.includes(keep) ? keep : "";
  renderPlans();
  const sel = $("#wind-plan"), chosen = sel.value;
  sel.innerHTML = "";
  state.plans.forEach(p => sel.add(new Option(p.name, p.name)));
  if (state.plans.some(p => p.name === chosen)) sel.value = chosen;
  windCli();
}

function renderPlans() {
  const root = $("#plans");
  root.innerHTML = "";
  if (!state.plans.length) { root.innerHTML = '<p class="muted">No plan yet: plan a picture above.</p>'; return; }
  for (const p of state.plans) {
    const card = document.createElement("div");
    card.className = "plan";
    card.dataset.plan = p.name;
    const img = document.createElement("img");
    if (p.preview) img.src = p.preview;
    img.alt = `${p.name}: the preview as woven`;
    card.appendChild(img);
    const info = document.createElement("div");
    info.className = "plan-info";
    const h = document.createElement("h3");
    h.textContent = p.name;
    info.appendChild(h);
    const line = document.createElement("div");
    line.className = "muted";
    p.colors.forEach(c => line.appendChild(swatch(c)));
    line.append(` ${p.pins} pins, ${p.lines} lines` + (p.machine ? `, for ${p.machine}` : ""));
    info.appendChild(line);
    if (p.estimate) {
      const est = document.createElement("div");
      est.className = "estimate";
      est.textContent = `about ${p.estimate.time} of winding, ${p.estimate.thread_m} m of thread`;
      info.appendChild(est);
      if (p.estimate.colors.length > 1 || p.colors[0] !== "#000000") {
        const per = document.createElement("div");
        per.className = "per-colour";
        p.estimate.colors.forEach(c => {
          const d = document.createElement("span");
          d.appendChild(swatch(c.color));
          d.append(` ${c.thread_m} m (${c.runs} run${c.runs > 1 ? "s" : ""}, ${c.time})`);
          per.appendChild(d);
        });
        info.appendChild(per);
      }
    } else {
      const est = document.createElement("div");
      est.className = "muted";
      est.textContent = "no machine: estimates come with plan --machine";
      info.appendChild(est);
    }
    for (const [target, j] of Object.entries(p.journals)) {
      const b = document.createElement("span");
      b.className = "badge " + (j.finished ? "ok" : j.resumable ? "warn" : "");
      b.textContent = `${target}: ` + (j.error ? "unreadable journal" : j.finished ? "wound" : `${j.done}/${j.total}` + (j.resumable ? ", resumable" : ""));
      info.appendChild(b);
    }
    const pick = document.createElement("button");
    pick.type = "button";
    pick.textContent = "Wind this";
    pick.className = "small";
    pick.onclick = () => { $("#wind-plan").value = p.name; if (p.machine) $("#wind-machine").value = p.machine; windCli(); $("#wind-card").scrollIntoView({behavior: "smooth"}); };
    info.appendChild(pick);
    card.appendChild(info);
    root.appendChild(card);
  }
}

async function submitPlan(ev) {
  ev.preventDefault();
  const f = $("#plan-form"), data = new FormData();
  const file = $("#picture").files[0];
  if (file) data.append("picture", file, file.name);
  else data.append("picture", $("#picture-name").value);
  for (const key of ["name", "machine", "pins", "lines", "colors", "spool_changes", "face"]) data.append(key, f[key].value);
  if (f.fit.checked) data.append("fit", "on");
  if (f.force.checked) data.append("force", "on");
  $("#plan-button").disabled = true;
  $("#plan-busy").hidden = false;
  show($("#plan-result"), "");
  try {
    const r = await api("/api/plans", data, {form: true});
    $("#plan-cli").textContent = r.command;
    show($("#plan-result"), r.said, "ok");
    await loadPlans();
    $("#wind-plan").value = r.plan.name;
    if (r.plan.machine) $("#wind-machine").value = r.plan.machine;
    windCli();
  } catch (e) {
    show($("#plan-result"), e.message, "error");
  } finally {
    $("#plan-button").disabled = false;
    $("#plan-busy").hidden = true;
  }
}

// ---- wind ------------------------------------------------------------------------------------------
async function windAction(resume) {
  const fields = windFields();
  show($("#wind-result"), "");
  try {
    await api("/api/wind", {...fields, resume});
    show($("#wind-result"), (resume ? "resuming" : "started") + ": the winding's card is below", "ok");
  } catch (e) { show($("#wind-result"), e.message, "error"); }
}

async function checkAction() {
  const fields = windFields();
  show($("#wind-result"), "checking the firmware's settings…");
  try {
    const r = await api("/api/check", fields);
    $("#wind-cli").textContent = r.command;
    show($("#wind-result"), r.said, "table " + (r.agree ? "ok" : "error"));
  } catch (e) { show($("#wind-result"), e.message, "error"); }
}

// ---- the live windings ---------------------------------------------------------------------------
async function drawingOf(plan) {
  if (!state.drawings[plan]) state.drawings[plan] = api(`/api/plans/${encodeURIComponent(plan)}/drawing`);
  return state.drawings[plan];
}

function cardFor(machine) {
  let card = state.cards[machine];
  if (card) return card;
  const el = $("#winding-template").content.firstElementChild.cloneNode(true);
  el.dataset.machine = machine;
  $("#windings").appendChild(el);
  card = {el, piece: new Piece($(".w-canvas", el), $(".w-overlay", el)), plan: null, asked: null, drawingFor: null};
  $(".w-stop", el).onclick = () => api(`/api/windings/${machine}/stop`, {}).catch(e => setText($(".w-outcome", el), e.message));
  $(".w-resume", el).onclick = () => {
    const w = state.live.windings[machine];
    api("/api/wind", {plan: w.plan, machine, target: w.target, resume: true}).catch(e => { $(".w-outcome", el).textContent = e.message; });
  };
  state.cards[machine] = card;
  return card;
}

function setText(el, text) { if (el.textContent !== text) el.textContent = text; }

async function renderWinding(machine, w) {
  const card = cardFor(machine), el = card.el;
  el.className = `card winding phase-${w.phase}` + (w.outcome ? ` outcome-${w.outcome.replace(" ", "-")}` : "");
  setText($(".w-machine", el), machine);
  setText($(".w-plan", el), `${w.plan} on the ${w.target === "port" ? "machine" : w.target}`);
  setText($(".w-phase", el), w.phase === "ended" ? w.outcome : w.phase);
  setText($(".w-cli", el), w.command);
  $(".w-bar", el).style.width = `${(100 * w.done / Math.max(1, w.total)).toFixed(1)}%`;
  setText($(".w-step", el), `${w.done} of ${w.total}`);
  setText($(".w-pin", el), w.pin === null ? "–" : String(w.pin));
  setText($(".w-eta", el), w.phase === "ended" ? "–" : fmt(w.eta_s));
  setText($(".w-elapsed", el), fmt(w.elapsed_s));
  const drawing = card.drawingFor === w.plan ? card.drawing : null;
  if (drawing && drawing.layers.length > 1 && w.layer !== null) {
    const lay = drawing.layers[w.layer];
    $(".w-layer", el).replaceChildren(swatch(lay.color), ` layer ${w.layer + 1} of ${drawing.layers.length}`);
  }
  $(".w-layer-dt", el).hidden = $(".w-layer", el).hidden = !(drawing && drawing.layers.length > 1);
  $(".w-stop", el).hidden = w.phase === "ended";
  $(".w-stop", el).disabled = w.phase === "stopping";
  setText($(".w-outcome", el), w.phase === "ended" ? (w.line || w.summary || `exit ${w.code}`) : "");
  setText($(".w-check", el), w.check ? w.check.text : "");
  $(".w-check", el).className = "w-check check-line " + (w.check ? (w.check.exact ? "ok" : "error") : "");
  const resumable = w.phase === "ended" && w.target !== "dry-run" && [1, 3, 130].includes(w.code);
  $(".w-resume", el).hidden = !resumable;
  const said = $(".w-said", el), lines = w.said.filter(t => t !== w.line && t !== w.summary).slice(-6);
  if (said.dataset.text !== lines.join("\n")) {
    said.dataset.text = lines.join("\n");
    said.replaceChildren(...lines.map(t => { const li = document.createElement("li"); li.textContent = t; return li; }));
  }
  renderQuestion(card, w);
  if (card.drawingFor !== w.plan) {
    card.drawingFor = w.plan;
    card.drawing = await drawingOf(w.plan);
    card.piece.setPlan(card.drawing);
  }
  card.piece.upTo(w.done);
}

function answer(machine, id, value) {
  return api(`/api/windings/${machine}/answer`, {id, value}).catch(e => {
    const card = state.cards[machine];
    if (card) setText($(".w-outcome", card.el), e.message);
  });
}

function button(text, cls, onclick) {
  const b = document.createElement("button");
  b.type = "button";
  b.textContent = text;
  if (cls) b.className = cls;
  b.onclick = onclick;
  return b;
}

function renderQuestion(card, w) {
  const box = $(".w-question", card.el), q = w.question;
  const key = q ? `${w.command}:${w.started}:${q.id}` : null;   // each question drawn once (its words came before it)
  if (key === card.asked) return;
  card.asked = key;
  box.hidden = !q;
  box.replaceChildren();
  box.dataset.ask = q ? String(q.id) : "";
  if (!q) return;
  const m = w.machine, text = document.createElement("p");
  text.className = "q-text";
  text.textContent = q.question || "";
  if (q.ask === "confirm") {
    box.append(text, button("Yes, go on", "primary", () => answer(m, q.id, true)), button("No, stop", "", () => answer(m, q.id, false)));
  } else if (q.ask === "choose") {
    box.append(text, ...q.choices.map(c => button(c, "primary", () => answer(m, q.id, c))));
  } else if (q.ask === "thread") {
    const h = document.createElement("h3");
    h.className = "spool";
    const first = !q.question.startsWith("Spool change");
    h.append(first ? "Tie the first thread on: " : "Spool change: tie on ", swatch(q.color), ` ${q.name || q.color} at pin ${q.pin}`);
    const sim = w.target === "simulator";
    box.append(h, text,
      button(sim ? `Tie it on at the simulator, then go on` : "It is tied on: go on", "primary", () => answer(m, q.id, true)),
      button("Not yet: stop here", "", () => answer(m, q.id, false)));
    const cli = document.createElement("p");
    cli.className = "muted";
    cli.textContent = sim ? `CLI: stringbot simulate --pty simulator/${m}.pty --tie-on '${q.color}' --pin ${q.pin}, then type the colour at the prompt`
                          : "CLI: type the colour's name (or y) at the prompt once it is on";
    box.appendChild(cli);
  } else if (q.ask === "jog") {
    renderGuide(box, w, q);
  }
}

function renderGuide(box, w, q) {
  const m = w.machine, machine = state.machines.find(x => x.name === m) || {pins: 300};
  const said = w.said.join("\n");
  const pin = (said.match(/pin (\d+) facing the head station/g) || []).pop();
  const gap = (said.match(/the gap between pins (\d+) and (\d+) faces the head/g) || []).pop();
  const h = document.createElement("h3");
  h.textContent = "Guided way back: jog to the reference";
  const how = document.createElement("p");
  how.className = "guide-text";
  how.textContent = (w.said.filter(t => /Guided resume|Bring the head IN|not a jog command|jog in smaller/.test(t)).pop() || "")
    .replace(/\s*Then jog with .*$/, "");
  box.append(h, how);
  const wrap = document.createElement("div");
  wrap.className = "guide";
  if (pin) wrap.appendChild(referenceSvg(machine.pins, +pin.match(/\d+/)[0], gap ? +gap.match(/\d+/)[0] : null));
  const pad = document.createElement("div");
  pad.className = "jog-pad";
  const row = (label, cmds) => {
    const r = document.createElement("div");
    r.className = "jog-row";
    const l = document.createElement("span");
    l.textContent = label;
    r.append(l, ...cmds.map(c => button(c.split(" ")[1], "jog", () => answer(m, q.id, c))));
    pad.appendChild(r);
  };
  row("ring (°)", ["ring -10", "ring -1", "ring -0.1", "ring +0.1", "ring +1", "ring +10"]);
  row("pin", ["pin -10", "pin -1", "pin +1", "pin +10"]);
  const stroke = Math.abs((machine.head_out_mm || 12) - (machine.head_in_mm || 0));
  row("head (mm)", [`head -${stroke}`, "head -1", "head -0.1", "head +0.1", "head +1", `head +${stroke}`]);
  const free = document.createElement("form");
  free.className = "jog-free";
  const input = document.createElement("input");
  input.placeholder = "ring +1.2, pin -1, head -12";
  free.append(input, button("Send", "", () => { if (input.value.trim()) answer(m, q.id, input.value.trim()); }));
  free.onsubmit = ev => { ev.preventDefault(); if (input.value.trim()) answer(m, q.id, input.value.trim()); };
  const ends = document.createElement("div");
  ends.className = "jog-row";
  ends.append(button("Done: it is there", "primary", () => answer(m, q.id, "done")),
              button("Quit (the machine stays)", "", () => answer(m, q.id, "quit")));
  pad.append(free, ends);
  const cli = document.createElement("p");
  cli.className = "muted";
  cli.textContent = "CLI: the same words at the jog> prompt of stringbot wind … --resume";
  pad.appendChild(cli);
  wrap.appendChild(pad);
  box.appendChild(wrap);
}

function onState(s) {
  state.live = s;
  if (s.plans_version !== state.plansVersion) { state.plansVersion = s.plans_version; loadPlans(); }
  const machines = Object.keys(s.windings).sort((a, b) => (s.windings[a].phase === "ended") - (s.windings[b].phase === "ended"));
  machines.forEach(m => renderWinding(m, s.windings[m]));
}

function connect() {
  const es = new EventSource("/api/events");
  es.onopen = () => { $("#live").className = "live on"; $("#live").textContent = "live"; };
  es.onerror = () => { $("#live").className = "live off"; $("#live").textContent = "reconnecting…"; };
  es.onmessage = ev => onState(JSON.parse(ev.data));
}

async function init() {
  state.machines = await api("/api/machines");
  for (const sel of [$("#plan-machine"), $("#wind-machine")]) {
    state.machines.forEach(m => sel.add(new Option(`${m.name} (${m.kind}, ${m.pins} pins)`, m.name)));
  }
  $("#wind-machine").value = "grbl-ring";
  $("#plan-form").addEventListener("input", planCli);
  $("#plan-form").addEventListener("change", planCli);
  $("#plan-form").addEventListener("submit", submitPlan);
  $("#wind-form").addEventListener("input", windCli);
  $("#wind-form").addEventListener("change", windCli);
  $("#wind-form").addEventListener("submit", ev => { ev.preventDefault(); windAction(false); });
  $("#resume-button").onclick = () => windAction(true);
  $("#check-button").onclick = checkAction;
  planCli();
  await loadPlans();
  connect();
}

document.addEventListener("DOMContentLoaded", init);
