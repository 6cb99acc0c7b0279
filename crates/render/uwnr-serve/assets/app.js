// uwnr serve: the page. Plain JS, no framework; everything it loads comes from this server.
"use strict";

const $ = (id) => document.getElementById(id);
const WATER_TYPES = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"];
const REF_PAGE = 16;
const MAX_ROWS = 4;
const POLL_MS = 150;
// This page's own name for its views: another tab's renders never make this one's stale.
const PAGE_ID = `${Date.now().toString(36)}-${Math.random().toString(36).slice(2, 10)}`;

const state = {
  info: null,
  clean: "0",          // "N" (index in --clean) or "uN" (a dropped photo)
  cleanName: "",
  depth: "prior",      // "prior", "beside" or the id of a dropped map
  selected: [],        // reference indices, in the order chosen
  refNames: {},
  refPage: 0,
  options: {},
  focus: null,         // key of the cell whose commands are shown
  cells: {},           // key -> {el, job, request, response}
};

// The token of a server that asks for one (it is in the address `uwnr serve` printed): added to
// every request this page makes, never kept in a cookie (a browser sends a host's cookies to
// every port of it, so other servers on the machine would receive the token).
const TOKEN = new URLSearchParams(location.search).get("token");

function withToken(url) {
  if (!TOKEN) return url;
  return `${url}${url.includes("?") ? "&" : "?"}token=${encodeURIComponent(TOKEN)}`;
}

function showMessage(text) {
  const m = $("message");
  if (!text) { m.hidden = true; m.textContent = ""; return; }
  m.hidden = false;
  m.textContent = text;
}

async function api(path, init) {
  const r = await fetch(withToken(path), init);
  const type = r.headers.get("Content-Type") || "";
  const body = type.startsWith("application/json") ? await r.json() : null;
  if (!r.ok) {
    const e = new Error((body && body.error) || `${r.status} ${r.statusText}`);
    e.status = r.status;
    throw e;
  }
  return body;
}

function defaultOptions(method) {
  const o = { seed: 0 };
  if (method === "uwnr") { o.precision = "f32"; o.depth_scale = ""; }
  if (method === "jerlov") { o.water_type = ""; o.depth_scale = ""; }
  if (method === "reinhard") { o.reinhard_space = ""; o.mean_only = false; }
  return o;
}

function parseRange(text) {
  const t = String(text).trim();
  if (!t) return null;
  const parts = t.split(",").map(Number);
  if (parts.some((x) => !Number.isFinite(x))) throw new Error(`depth scale ${t}: expected M or MIN,MAX`);
  return parts.length === 1 ? [parts[0], parts[0]] : [parts[0], parts[1]];
}

// The options as the server reads them (unset ones left out, as unset CLI flags).
function methodOptions(method) {
  const o = state.options[method];
  const out = { method, seed: Number(o.seed) || 0 };
  if (o.precision && o.precision !== "f32") out.precision = o.precision;
  if (o.water_type) out.water_type = o.water_type;
  if (o.depth_scale !== undefined) { const r = parseRange(o.depth_scale); if (r) out.depth_scale = r; }
  if (o.reinhard_space) out.reinhard_space = o.reinhard_space;
  if (o.mean_only) out.mean_only = true;
  return out;
}

function needsReference(method) {
  return method !== "uwgan" && method !== "jerlov";
}

function cleanSource() {
  return state.clean.startsWith("u") ? { upload: state.clean } : { index: Number(state.clean) };
}

function depthChoice() {
  if (state.depth === "prior" || state.depth === "beside") return state.depth;
  return { upload: state.depth };
}

// ---- options panel ----
function buildOptions() {
  const box = $("options");
  box.innerHTML = "";
  for (const method of state.info.methods) {
    state.options[method] = defaultOptions(method);
    const div = document.createElement("div");
    div.className = "opt";
    div.dataset.method = method;
    div.innerHTML = `<b>${method}</b>`;
    const add = (label, el, key) => {
      const l = document.createElement("label");
      l.textContent = label;
      el.dataset.key = key;
      el.dataset.method = method;
      el.addEventListener("change", () => {
        state.options[method][key] = el.type === "checkbox" ? el.checked : el.value;
        renderMethod(method);
      });
      l.appendChild(el);
      div.appendChild(l);
    };
    const input = (type, value) => { const i = document.createElement("input"); i.type = type; if (type === "checkbox") i.checked = value; else i.value = value; return i; };
    const select = (values) => {
      const s = document.createElement("select");
      for (const [v, t] of values) { const o = document.createElement("option"); o.value = v; o.textContent = t; s.appendChild(o); }
      return s;
    };
    add("seed", input("number", 0), "seed");
    if (method === "uwnr") {
      add("depth scale m", input("text", ""), "depth_scale");
      add("precision", select([["f32", "f32"], ["bf16", "bf16"]]), "precision");
    }
    if (method === "jerlov") {
      add("water type", select([["", "random"], ...WATER_TYPES.map((t) => [t, t])]), "water_type");
      add("depth scale m", input("text", ""), "depth_scale");
    }
    if (method === "reinhard") {
      add("space", select([["", "lalphabeta"], ["lab", "lab"], ["rgb", "rgb"]]), "reinhard_space");
      add("mean only", input("checkbox", false), "mean_only");
    }
    box.appendChild(div);
  }
}

// ---- the grid of renders ----
function rows() {
  return state.selected.length ? state.selected.slice(0, MAX_ROWS) : [null];
}

function buildGrid() {
  const grid = $("grid");
  grid.innerHTML = "";
  state.cells = {};
  rows().forEach((ref, r) => {
    const label = document.createElement("div");
    label.className = "rowlabel";
    label.textContent = ref === null ? "no reference selected" : `reference ${state.refNames[ref] || ref}`;
    grid.appendChild(label);
    for (const method of state.info.methods) {
      const key = `${method}|${ref === null ? "-" : ref}`;
      const cell = document.createElement("div");
      cell.className = "cell";
      cell.dataset.method = method;
      cell.dataset.row = String(r);
      cell.dataset.key = key;
      cell.innerHTML = `<div class="view"><img class="base show" alt=""><img class="render" alt=""></div>
        <div class="cap"><b>${method}</b><span class="state"></span></div>
        <div class="cap"><button class="cmdbtn">command</button><button class="dl">full-res &#x2913;</button></div>`;
      cell.querySelector(".base").src = cleanUrl();
      cell.addEventListener("click", () => setFocus(key));
      cell.querySelector(".dl").addEventListener("click", (ev) => { ev.stopPropagation(); download(key); });
      grid.appendChild(cell);
      state.cells[key] = { el: cell, method, ref, job: null, request: null, response: null };
    }
  });
  applySplit();
  for (const key of Object.keys(state.cells)) renderCell(key);
}

function cleanUrl() {
  return withToken(`/api/clean/image?clean=${encodeURIComponent(state.clean)}`);
}

function applySplit() {
  const v = Number($("split").value);
  for (const img of document.querySelectorAll(".cell img.render")) {
    img.style.clipPath = `inset(0 ${100 - v}% 0 0)`;
  }
}

function setCellState(cell, st, text) {
  cell.el.dataset.state = st;
  cell.el.querySelector(".state").textContent = text;
  cell.el.querySelector(".state").title = text;
}

function requestFor(cell, size) {
  const k = Number($("draw-k").value) || 1;
  return {
    view: `${PAGE_ID}|${size === "full" ? `${cell.el.dataset.key}|full` : cell.el.dataset.key}`,
    clean: cleanSource(),
    depth: depthChoice(),
    reference: cell.ref,
    options: methodOptions(cell.method),
    size,
    dataset: { k: state.selected.length || k, seed: Number($("draw-seed").value) || 0 },
  };
}

async function submit(request) {
  return api("/api/render", {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify(request),
  });
}

async function renderCell(key) {
  const cell = state.cells[key];
  if (!cell) return;
  if (cell.ref === null && needsReference(cell.method)) {
    cell.job = null;
    cell.el.querySelector(".render").removeAttribute("src");
    setCellState(cell, "idle", "select a reference");
    return;
  }
  let request;
  try { request = requestFor(cell, "preview"); } catch (e) { setCellState(cell, "failed", e.message); return; }
  setCellState(cell, "queued", "queued");
  const token = {};
  cell.token = token;
  let answer;
  try {
    answer = await submit(request);
  } catch (e) {
    if (cell.token !== token) return;
    setCellState(cell, "failed", e.message);
    if (e.status === 503) {
      setCellState(cell, "busy", `${e.message} (retrying)`);
      setTimeout(() => { if (cell.token === token) renderCell(key); }, 1500);
    }
    return;
  }
  if (cell.token !== token) return;
  cell.job = answer.job;
  cell.request = request;
  cell.response = answer;
  if (!state.focus || !state.cells[state.focus]) setFocus(key);
  else if (state.focus === key) showCommands();
  const status = await poll(answer.job, (s) => {
    if (cell.token !== token) return false;
    if (s.state === "queued") setCellState(cell, "queued", s.ahead ? `queued (${s.ahead} ahead)` : "queued");
    if (s.state === "running") setCellState(cell, "running", `rendering ${(s.elapsed_ms / 1000).toFixed(1)} s`);
    return true;
  });
  if (cell.token !== token || !status) return;
  if (status.state === "done") {
    const img = cell.el.querySelector(".render");
    img.onload = () => { if (cell.token === token) setCellState(cell, "done", `${status.width}x${status.height}, ${status.millis} ms`); };
    img.src = withToken(`/api/job/${answer.job}/image`);
    cell.el.dataset.job = String(answer.job);
  } else if (status.state === "failed") {
    setCellState(cell, "failed", status.error);
  } else if (status.state === "stale") {
    // Replaced by a newer request for this cell that this page did not make (it would have
    // changed the cell's token): render again rather than wait.
    setCellState(cell, "queued", "replaced; rendering again");
    renderCell(key);
  }
}

// Polls a job until it ends; `onUpdate` returns false to stop.
async function poll(job, onUpdate) {
  for (;;) {
    let s;
    try { s = await api(`/api/job/${job}`); } catch (e) { return { state: "failed", error: e.message }; }
    if (s.state === "done" || s.state === "failed" || s.state === "stale") return s;
    if (!onUpdate(s)) return null;
    await new Promise((res) => setTimeout(res, POLL_MS));
  }
}

function renderMethod(method) {
  for (const [key, cell] of Object.entries(state.cells)) if (cell.method === method) renderCell(key);
}

function renderAll() {
  for (const key of Object.keys(state.cells)) renderCell(key);
}

// ---- commands and downloads ----
function setFocus(key) {
  state.focus = key;
  for (const c of Object.values(state.cells)) c.el.classList.toggle("focus", c.el.dataset.key === key);
  showCommands();
}

function showCommands() {
  const cell = state.cells[state.focus];
  const r = cell && cell.response;
  $("render-cmd").textContent = r ? r.render_command : "";
  $("dataset-cmd").textContent = r ? r.dataset_command : "";
  $("render-cmd").dataset.request = cell && cell.request ? JSON.stringify(cell.request) : "";
  $("cmd-for").textContent = cell ? `${cell.method}, ${cell.ref === null ? "no reference" : state.refNames[cell.ref] || cell.ref}` : "";
  $("cmd-notes").textContent = r ? [
    "The render command writes the full-resolution image of this cell, pixel for pixel what the download gives.",
    "The dataset command draws its own references per photo (K, seed) and draws per-pair parameters from its seed.",
    ...r.notes,
  ].join(" ") : "";
}

async function download(key) {
  const cell = state.cells[key];
  if (!cell || !cell.response) return;
  const btn = cell.el.querySelector(".dl");
  btn.disabled = true;
  btn.textContent = "rendering...";
  try {
    const answer = await submit(requestFor(cell, "full"));
    const status = await poll(answer.job, (s) => { btn.textContent = s.state === "running" ? `rendering ${(s.elapsed_ms / 1000).toFixed(1)} s` : "queued"; return true; });
    if (status.state !== "done") throw new Error(status.error || status.state);
    const name = answer.render_command.split(" ").pop().replace(/'/g, "");
    const a = document.createElement("a");
    a.href = withToken(`/api/job/${answer.job}/image?download=${encodeURIComponent(name)}`);
    a.download = name;
    document.body.appendChild(a);
    a.click();
    a.remove();
  } catch (e) {
    showMessage(`full-resolution render: ${e.message}`);
  } finally {
    btn.disabled = false;
    btn.innerHTML = "full-res &#x2913;";
  }
}

async function copy(id) {
  const text = $(id).textContent;
  try { await navigator.clipboard.writeText(text); } catch (e) {
    const range = document.createRange();
    range.selectNodeContents($(id));
    const sel = window.getSelection();
    sel.removeAllRanges();
    sel.addRange(range);
    document.execCommand("copy");
  }
}

// ---- clean image and depth ----
function loadClean() {
  $("clean-img").src = cleanUrl();
  loadDepth();
  buildGrid();
}

function loadDepth() {
  const img = $("depth-img");
  const url = withToken(`/api/clean/depth?clean=${encodeURIComponent(state.clean)}&depth=${encodeURIComponent(state.depth)}`);
  fetch(url).then(async (r) => {
    if (!r.ok) { const b = await r.json(); showMessage(`depth: ${b.error}`); img.removeAttribute("src"); return; }
    showMessage("");
    img.src = URL.createObjectURL(await r.blob());
  });
}

function fillCleanSelect(selected) {
  const s = $("clean-select");
  s.innerHTML = "";
  for (const c of state.info.cleans) {
    const o = document.createElement("option");
    o.value = String(c.index);
    o.textContent = c.rel + (c.depth_beside ? "  (depth/)" : "");
    s.appendChild(o);
  }
  for (const u of state.uploads || []) {
    const o = document.createElement("option");
    o.value = u.id;
    o.textContent = `dropped: ${u.name}`;
    s.appendChild(o);
  }
  s.value = selected;
}

async function upload(file, kind) {
  const r = await fetch(withToken(`/api/upload?kind=${kind}&name=${encodeURIComponent(file.name)}`), { method: "POST", body: file });
  const b = await r.json();
  if (!r.ok) throw new Error(b.error);
  return b;
}

function dropZone(el, onFile) {
  el.addEventListener("dragover", (e) => { e.preventDefault(); el.classList.add("over"); });
  el.addEventListener("dragleave", () => el.classList.remove("over"));
  el.addEventListener("drop", async (e) => {
    e.preventDefault();
    el.classList.remove("over");
    const f = e.dataTransfer.files[0];
    if (!f) return;
    if (f.size > state.info.max_upload_bytes) { showMessage(`${f.name} is ${f.size} bytes, more than the ${state.info.max_upload_bytes} this server accepts`); return; }
    try { await onFile(f); showMessage(""); } catch (err) { showMessage(`${f.name}: ${err.message}`); }
  });
}

// ---- references ----
function rgb(c) {
  return `rgb(${c.map((v) => Math.round(v * 255)).join(",")})`;
}

async function loadReferences() {
  const page = await api(`/api/references?page=${state.refPage}&per=${REF_PAGE}`);
  const grid = $("ref-grid");
  grid.innerHTML = "";
  for (const item of page.items) {
    state.refNames[item.index] = item.rel;
    const d = document.createElement("div");
    d.className = "ref";
    d.dataset.index = String(item.index);
    d.classList.toggle("selected", state.selected.includes(item.index));
    if (item.error) {
      d.innerHTML = `<div class="err"></div>`;
      d.querySelector(".err").textContent = `${item.rel}: ${item.error}`;
      d.style.minHeight = "60px";
    } else {
      d.innerHTML = `<img alt=""><span class="sw mean"></span><span class="sw veil"></span>`;
      d.querySelector("img").src = withToken(`/api/reference/${item.index}/thumb`);
      d.querySelector(".mean").style.background = rgb(item.mean);
      d.querySelector(".veil").style.background = rgb(item.veil);
      d.title = `${item.rel}\nmean colour ${item.mean.map((v) => v.toFixed(2)).join(", ")} (square)\nveiling light ${item.veil.map((v) => v.toFixed(2)).join(", ")} (circle)`;
      d.addEventListener("click", () => toggleReference(item.index));
    }
    grid.appendChild(d);
  }
  const pages = Math.max(1, Math.ceil(page.total / REF_PAGE));
  $("ref-page").textContent = `page ${state.refPage + 1} / ${pages}`;
  $("ref-count").textContent = `(${page.total})`;
}

function markSelected() {
  for (const d of document.querySelectorAll(".ref")) d.classList.toggle("selected", state.selected.includes(Number(d.dataset.index)));
}

function toggleReference(i) {
  const at = state.selected.indexOf(i);
  if (at >= 0) state.selected.splice(at, 1); else state.selected.push(i);
  markSelected();
  buildGrid();
}

async function drawReferences() {
  const k = Number($("draw-k").value) || 1;
  const seed = Number($("draw-seed").value) || 0;
  const d = await api(`/api/draw?clean=${encodeURIComponent(state.clean)}&k=${k}&seed=${seed}`);
  state.selected = d.references;
  for (const i of d.references) if (!(i in state.refNames)) state.refNames[i] = `#${i}`;
  markSelected();
  buildGrid();
}

async function pollStatus() {
  try {
    const s = await api("/api/status");
    $("status").textContent = `renders: ${s.running} running, ${s.queued} waiting (queue ${s.capacity})`;
  } catch (e) {
    $("status").textContent = `server unreachable: ${e.message}`;
  }
  setTimeout(pollStatus, 1000);
}

async function main() {
  state.info = await api("/api/info");
  state.uploads = [];
  buildOptions();
  fillCleanSelect("0");
  if (!state.info.cleans.length) showMessage("the --clean folder holds no images: drop one in");
  $("clean-select").addEventListener("change", (e) => {
    state.clean = e.target.value;
    loadClean();
  });
  $("depth-select").addEventListener("change", (e) => {
    state.depth = e.target.value;
    loadDepth();
    renderAll();
  });
  dropZone($("clean-drop"), async (f) => {
    const u = await upload(f, "clean");
    state.uploads.push(u);
    state.clean = u.id;
    fillCleanSelect(u.id);
    loadClean();
  });
  dropZone($("depth-drop"), async (f) => {
    const u = await upload(f, "depth");
    const o = document.createElement("option");
    o.value = u.id;
    o.textContent = `dropped: ${u.name}`;
    $("depth-select").appendChild(o);
    $("depth-select").value = u.id;
    state.depth = u.id;
    loadDepth();
    renderAll();
  });
  $("split").addEventListener("input", applySplit);
  $("draw").addEventListener("click", () => drawReferences().catch((e) => showMessage(e.message)));
  $("ref-prev").addEventListener("click", () => { if (state.refPage > 0) { state.refPage--; loadReferences(); } });
  $("ref-next").addEventListener("click", () => {
    if ((state.refPage + 1) * REF_PAGE < state.info.references) { state.refPage++; loadReferences(); }
  });
  $("ref-clear").addEventListener("click", () => { state.selected = []; markSelected(); buildGrid(); });
  for (const b of document.querySelectorAll("[data-copy]")) b.addEventListener("click", () => copy(b.dataset.copy));
  if (state.info.cleans.length) loadClean();
  await loadReferences();
  pollStatus();
}

main().catch((e) => showMessage(`could not start: ${e.message}`));
