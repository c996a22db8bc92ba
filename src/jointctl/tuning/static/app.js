// jointctl tuning page: live plots (uPlot), live gains, command sources, controls, measurements.
// Everything the page does goes through one websocket as JSON requests; the server checks
// each one and answers ok or error. The page keeps the last 60 s of samples it was sent.
"use strict";

(function () {
  const KEEP_S = 60;
  const page = {            // read by the browser tests
    connected: false, hello: null, messages: 0, dataMessages: 0, points: 0, lastTime: null,
    draws: 0, measure: null, status: null, errors: [], replies: [],
    series: () => data,
  };
  window.jointctlPage = page;
  page.send = (request) => send(request);  // for analysis.js

  const $ = (id) => document.getElementById(id);
  const data = { t: [], reference: [], position: [], velocity: [], effort: [], force: [] };
  let ws = null;
  let windowS = 10;
  let charts = [];
  let units = {};
  let dirty = false;
  let joint = null;          // the joint plotted
  let shownJoint = null;     // the joint the server last agreed to send
  const accepted = {};      // last accepted value of each gain input, by input id

  // -- connection ----------------------------------------------------------------------------------
  function connect() {
    const scheme = location.protocol === "https:" ? "wss://" : "ws://";
    ws = new WebSocket(scheme + location.host + "/ws");
    ws.onopen = () => { page.connected = true; setState("connected"); };
    ws.onclose = (event) => {
      page.connected = false;
      setState("disconnected (" + event.code + ")");
      if (event.code === 1009) showError("message: larger than the server accepts; nothing changed");
      setTimeout(connect, 1000);
    };
    ws.onmessage = (event) => {
      page.messages += 1;
      let message;
      try { message = JSON.parse(event.data); } catch (e) { showError("unreadable message from the server"); return; }
      const handler = handlers[message.type];
      if (handler) handler(message);
      if (message.type === "scene") page.scene = message;  // for a 3D view that loads after it came
      window.dispatchEvent(new CustomEvent("jointctl:" + message.type, { detail: message }));  // analysis.js, view3d.js
    };
  }

  function send(request) {
    if (!ws || ws.readyState !== WebSocket.OPEN) { showError("not connected: nothing was sent"); return; }
    ws.send(JSON.stringify(request));
  }

  // A number when the text is one, else the text itself: the server says what is wrong with it.
  function numberOrText(text) {
    const trimmed = String(text).trim();
    const value = Number(trimmed);
    return trimmed !== "" && Number.isFinite(value) ? value : trimmed;
  }

  // -- messages --------------------------------------------------------------------------------------
  const handlers = {
    hello(m) {
      page.hello = m;
      $("robot").textContent = m.robot + (m.scenario ? " · " + m.scenario : "");
      fillSelect($("joint"), m.joints.map((j) => j.name), m.joint);
      fillSelect($("source-controller"), m.controllers.map((c) => c.name));
      $("drop").hidden = !m.can_drop;
      $("gravity").value = m.gravity_z_m_s2;
      $("rate").textContent = "plot " + m.display_hz.toFixed(0) + " samples/s, " + m.stream_hz.toFixed(0) + " updates/s";
      buildGains(m.gains);
      shownJoint = m.joint;
      setJoint(m.joint);
      const sources = m.sources || {};
      showSources(Object.fromEntries(Object.entries(sources).map(([c, s]) => [c, Object.fromEntries(
        Object.entries(s).filter(([k]) => k !== "origin"))])),
        Object.fromEntries(Object.entries(sources).map(([c, s]) => [c, s.origin])));
    },
    data(m) {
      if (m.joint !== joint) return;  // sent before a joint change arrived
      page.dataMessages += 1;
      append(m.t, m.series);
    },
    reset() { clearData(); goLive(); },
    status(m) {
      page.status = m;
      setState(m.paused ? "paused" : "running");
      $("clock").textContent = "t = " + m.time_s.toFixed(3) + " s · " +
        (m.gravity_z_m_s2 === null ? "real hardware (no gravity or weight to set)" : "gravity " + m.gravity_z_m_s2 + " m/s²") +
        (m.weight_dropped ? " · weight dropped" : "");
      showLate(m);
      showSources(m.sources, m.source_origins || {});
      if (m.error) showError(m.error);
    },
    measure(m) { page.measure = m; showMeasure(m); },
    ok(m) {
      reply(m);
      if (m.request === "gain") {
        const id = gainId(m.controller, m.name);
        accepted[id] = m.value;
        const slider = $(id + "-slider");
        if (slider && m.value > Number(slider.max)) slider.max = sliderMax(m.value);
        if (slider) slider.value = m.value;
      }
      if (m.request === "joint") shownJoint = m.joint;
      if (m.request === "gravity") $("gravity").value = m.value;
    },
    saved(m) {
      reply(m);
      const link = document.createElement("a");
      link.href = URL.createObjectURL(new Blob([m.yaml], { type: "text/yaml" }));
      link.download = m.path.split("/").pop();
      link.textContent = "download";
      const saved = $("saved");
      saved.textContent = "wrote " + m.path + " ";
      saved.appendChild(link);
    },
    error(m) {
      page.errors.push(m);
      showError(m.message);
      restoreGainInputs();
      if (m.request === "joint") setJoint(shownJoint);  // the server kept plotting that one
    },
  };

  function reply(m) {
    page.replies.push(m);
    if (m.request === "source") formEdited = false;  // accepted: the form may follow the running source again
    $("error").hidden = true;
    const item = document.createElement("li");
    item.textContent = "ok: " + m.request + (m.value !== undefined ? " = " + m.value : "");
    log(item);
  }

  function showError(text) {
    const box = $("error");
    box.textContent = text;
    box.hidden = false;
    const item = document.createElement("li");
    item.className = "bad";
    item.textContent = "refused: " + text;
    log(item);
  }

  function log(item) {
    const list = $("log");
    list.prepend(item);
    while (list.children.length > 20) list.lastChild.remove();
  }

  function setState(text) { $("state").textContent = text; }

  function fillSelect(select, names, chosen) {
    select.replaceChildren(...names.map((name) => {
      const option = document.createElement("option");
      option.value = option.textContent = name;
      return option;
    }));
    if (chosen !== undefined) select.value = chosen;
  }

  function describeSource(s) {
    const params = Object.entries(s).filter(([k]) => k !== "type" && k !== "origin").map(([k, v]) => k + " " + v + (k === "at" ? " s" : ""));
    return s.type + (params.length ? " (" + params.join(", ") + ")" : "");
  }

  // -- late cycles ------------------------------------------------------------------------------------
  // A late cycle finished after its deadline on the wall clock (the pacer did not wait before the next).
  // Too many: more than late_share_limit of the cycles (1 %), over the whole run or over the last
  // late_recent_s seconds (5 s) of statuses.
  const timing = [];  // [wall-clock ms, late, cycles] of recent statuses

  // The figures of ``history`` ([wall-clock ms, late, cycles], oldest first, the newest last): the share
  // late since the start and over the history (the last ``recentS`` seconds), and whether that is too many.
  function lateFigures(history, limit) {
    const [, late, cycles] = history[history.length - 1], [, late0, cycles0] = history[0];
    const share = cycles > 0 ? late / cycles : 0;
    const recentShare = cycles - cycles0 > 0 ? (late - late0) / (cycles - cycles0) : 0;
    return { share: share, recentShare: recentShare, recentCycles: cycles - cycles0, tooMany: share > limit || recentShare > limit };
  }
  page.lateFigures = lateFigures;  // for the tests

  function showLate(m) {
    const box = $("late");
    if (m.late_cycles === undefined || !m.cycles) { box.hidden = true; return; }
    const limit = page.hello.late_share_limit, recentS = page.hello.late_recent_s;
    const now = performance.now();
    if (timing.length && m.cycles < timing[timing.length - 1][2]) timing.length = 0;  // another server
    timing.push([now, m.late_cycles, m.cycles]);
    while (timing.length > 2 && now - timing[1][0] >= recentS * 1000) timing.shift();
    const figures = lateFigures(timing, limit);
    page.late = figures;
    box.hidden = false;
    box.classList.toggle("too-many", figures.tooMany);
    box.textContent = "late cycles " + pct(figures.share) + " (" + m.late_cycles + " of " + m.cycles + ")" +
      (figures.recentCycles > 0 ? " · last " + recentS + " s " + pct(figures.recentShare) : "") + (figures.tooMany ? " · too many" : "");
    box.title = "Late cycles: control cycles that finished after their deadline (the loop fell behind the wall " +
      "clock and the next cycle started at once, without waiting). Too many (highlighted): more than " +
      pct(limit) + " of the cycles, since the start or in the last " + recentS + " s. In simulation loop time stays " +
      "exact (cycle × period) and the physics is unchanged; the plots and the robot then run slower than the wall " +
      "clock. On real hardware a late cycle is a command sent late: lower --speed, close other programs or " +
      "use a real-time kernel.";
  }
  function pct(share) { return (100 * share).toFixed(share < 0.1 ? 2 : 1) + " %"; }

  // -- the command source running ---------------------------------------------------------------------
  // The form shows the source that feeds the chosen controller (the scenario's own, or one applied from
  // a page) whenever that source changes, and when another controller is chosen; never while the user
  // is editing it (changed a field since their last source was accepted; a refused one stays to be
  // corrected): a status arriving then would undo their choice.
  let sourcesNow = {}, originsNow = {}, formEdited = false;
  const formShows = {};  // controller -> JSON of the source the form was last filled from
  function showSources(sources, origins) {
    sourcesNow = sources;
    originsNow = origins;
    const lines = Object.entries(sources).map(([c, s]) => c + ": " + describeSource(s) +
      (origins[c] === "scenario" ? " (the scenario's own source)" : ""));
    const now = $("source-now");
    now.textContent = lines.length ? "running: " + lines.join("; ") : "no source: controllers hold";
    now.classList.toggle("scenario", Object.values(origins).includes("scenario"));
    const controller = $("source-controller").value;
    const running = sources[controller];
    if (running && !formEdited && formShows[controller] !== JSON.stringify(running)) fillSourceForm(controller);
  }

  function fillSourceForm(controller) {
    const s = sourcesNow[controller];
    formShows[controller] = JSON.stringify(s);
    if (!s) return;
    const set = (id, value) => { if (value !== undefined && value !== null) $(id).value = value; };
    if (s.type === "constant") set("constant-value", s.value);
    if (s.type === "step") { set("step-from", s.from); set("step-to", s.to); set("step-at", s.at); }
    if (s.type === "sine") {
      set("sine-amplitude", s.amplitude); set("sine-frequency", s.frequency_hz);
      set("sine-offset", s.offset === undefined ? 0 : s.offset); set("sine-rate", s.rate_hz === undefined ? 100 : s.rate_hz);
    }
    if (s.type === "expression") { set("expression-text", s.expression); set("expression-rate", s.rate_hz === undefined ? 100 : s.rate_hz); }
    if ([...$("source-type").options].some((o) => o.value === s.type)) $("source-type").value = s.type;
    showSourceParams();
  }

  // -- plots -------------------------------------------------------------------------------------------
  // Three charts of the chosen joint: position (with its reference), velocity, and effort with the
  // force sensor's force on an axis of its own (right), so an impact's kilonewtons leave the effort
  // readable. The x axis is loop time; "view" says which window is shown: the newest (live) or one
  // the user stopped at (frozen: data keep arriving, the plots stay). Each chart's y axes fit their data
  // unless zoomed or panned (yManual), which double-click or Reset zoom undoes.
  const FROZEN_KEEP_S = 600;  // while frozen, at most this much loop time is kept to scrub through
  const view = { live: true, end: 0 };
  page.view = view;

  function clearData() {
    for (const key of Object.keys(data)) data[key] = [];
    page.points = 0;
    view.end = 0;
    dirty = true;
  }

  function append(t, series) {
    const force = Object.keys(series).find((k) => k.startsWith("force:"));
    for (let k = 0; k < t.length; k++) {
      data.t.push(t[k]);
      data.reference.push(series.reference[k]);
      data.position.push(series.position[k]);
      data.velocity.push(series.velocity[k]);
      data.effort.push(series.effort[k]);
      data.force.push(force ? series[force][k] : null);
    }
    page.points += t.length;
    page.lastTime = data.t[data.t.length - 1];
    // Keep KEEP_S seconds (more while frozen, to scrub back through); drop the old part in one go
    // now and then, not a sample at a time.
    const keep = view.live ? KEEP_S : Math.max(KEEP_S, Math.min(FROZEN_KEEP_S, page.lastTime - view.end + windowS + 1));
    const cut = lowerBound(data.t, page.lastTime - keep);
    if (cut > 2000) for (const key of Object.keys(data)) data[key] = data[key].slice(cut);
    if (view.live) dirty = true;
    else scrubRange();
  }

  function lowerBound(values, x) {
    let lo = 0, hi = values.length;
    while (lo < hi) { const mid = (lo + hi) >> 1; if (values[mid] < x) lo = mid + 1; else hi = mid; }
    return lo;
  }

  function setJoint(name) {
    joint = name;
    $("joint").value = name;
    clearData();
    buildCharts();
    goLive();  // another joint's data: nothing of the paused window is left
  }

  // Tick labels: as many decimals as the tick spacing has, never "-0", never two alike.
  function decimals(step) {
    for (let d = 0; d < 12; d++) {
      const scaled = step * Math.pow(10, d);
      if (Math.abs(scaled - Math.round(scaled)) < 1e-6 * Math.max(1, scaled)) return d;
    }
    return 12;
  }
  function tickLabel(value, step) {
    const text = value.toFixed(decimals(step));
    return Number(text) === 0 ? "0" : text;
  }
  page.tickLabel = tickLabel;  // for the tests

  // A y range fitting [min, max] with 8 % margins, at least ``minSpan`` wide (a joint at rest would
  // otherwise show micro-units of noise), or the range the user zoomed or panned to.
  function yRange(minSpan) {
    return (u, min, max, key) => {
      const manual = u.yManual && u.yManual[key];
      if (manual) return manual.slice();
      if (min === null || max === null || !Number.isFinite(min) || !Number.isFinite(max)) return [-minSpan / 2, minSpan / 2];
      const pad = 0.08 * (max - min);
      let lo = min - pad, hi = max + pad;
      if (hi - lo < minSpan) { const mid = (lo + hi) / 2; lo = mid - minSpan / 2; hi = mid + minSpan / 2; }
      return [lo, hi];
    };
  }

  function chartHeight() {
    const section = document.querySelector(".plots");
    let free = section.clientHeight;
    for (const child of section.children) if (!child.classList.contains("plot")) free -= child.offsetHeight + 6;
    // Each chart: its canvas plus its legend (about 26 px) and margins.
    return Math.max(120, Math.floor(free / 3) - 40);
  }

  function chartWidth(element) { return Math.max(300, element.clientWidth - 2); }

  function buildCharts() {
    for (const chart of charts) chart.destroy();
    const info = page.hello.joints.find((j) => j.name === joint);
    const prismatic = Boolean(info && info.prismatic);
    const unit = prismatic ? "m" : "rad";
    const effortUnit = prismatic ? "N" : "N·m";
    const hasForce = page.hello.sensors.length > 0;
    units = { reference: unit, position: unit, velocity: unit + "/s", effort: effortUnit, force: "N" };
    // [element, [[series, colour, scale]], {scale: [axis label, side, smallest span]}]
    const specs = [
      ["plot-position", [["reference", "#d62728", "y"], ["position", "#1f77b4", "y"]],
        { y: ["position (" + unit + ")", 3, prismatic ? 0.002 : 0.005] }],
      ["plot-velocity", [["velocity", "#2ca02c", "y"]], { y: ["velocity (" + unit + "/s)", 3, 0.01] }],
      ["plot-effort", [["effort", "#9467bd", "y"]].concat(hasForce ? [["force", "#8c564b", "force"]] : []),
        Object.assign({ y: ["effort (" + effortUnit + ")", 3, 1] },
                      hasForce ? { force: ["sensor force z (N)", 1, 1] } : {})],
    ];
    const height = chartHeight();
    charts = specs.map(([id, lines, scales]) => {
      const element = $(id);
      element.replaceChildren();
      const scaleOptions = { x: { time: false } };
      const axes = [{ label: "loop time (s)", size: 36, labelSize: 16, values: (u, splits, _, __, step) => splits.map((v) => tickLabel(v, step)) }];
      for (const [key, [label, side, minSpan]] of Object.entries(scales)) {
        scaleOptions[key] = { range: yRange(minSpan) };
        axes.push({ scale: key, label: label, side: side, size: 72, labelSize: 18,
                    grid: { show: side === 3 }, values: (u, splits, _, __, step) => splits.map((v) => tickLabel(v, step)) });
      }
      // A blank right axis where a chart has no second one: the time axes of the three line up.
      if (axes.length === 2) axes.push({ scale: "y", side: 1, size: 72, label: " ", labelSize: 18, grid: { show: false }, ticks: { show: false }, values: () => [] });
      const chart = new uPlot({
        width: chartWidth(element), height: height,
        scales: scaleOptions,
        cursor: { sync: { key: "jointctl" }, drag: { x: false, y: false, setScale: false }, bind: { dblclick: () => null } },
        axes: axes,
        series: [{ label: "t", value: (u, v) => v === null ? "--" : v.toFixed(3) }].concat(lines.map(([name, color, scale]) => ({
          label: name + " (" + units[name] + ")", stroke: color, width: 1.5, scale: scale }))),
      }, [[], ...lines.map(() => [])], element);
      chart.keys = lines.map(([name]) => name);
      chart.yScales = Object.keys(scales);
      chart.yManual = {};
      bindChart(chart);
      return chart;
    });
    page.charts = charts;
    dirty = true;
  }

  // Wheel: zoom the y axis under the pointer about the pointer; drag: pan y (and time, which
  // freezes the plots); double-click: fit the y axes again.
  function bindChart(chart) {
    const over = chart.over;
    const scaleAt = (x) => (chart.yScales.length > 1 && x > over.clientWidth / 2 ? chart.yScales[1] : chart.yScales[0]);
    over.addEventListener("wheel", (event) => {
      event.preventDefault();
      zoomY(chart, scaleAt(event.offsetX), Math.exp(0.0015 * event.deltaY), event.offsetY);
    }, { passive: false });
    over.addEventListener("dblclick", () => { chart.yManual = {}; dirty = true; });
    let drag = null;
    over.addEventListener("pointerdown", (event) => {
      if (event.button !== 0) return;
      drag = { x: event.clientX, y: event.clientY, end: shownEnd(), ranges: {}, moved: false };
      for (const key of chart.yScales) drag.ranges[key] = [chart.scales[key].min, chart.scales[key].max];
      over.setPointerCapture(event.pointerId);
    });
    over.addEventListener("pointermove", (event) => {
      if (!drag) return;
      const dx = event.clientX - drag.x, dy = event.clientY - drag.y;
      if (!drag.moved && Math.abs(dx) < 3 && Math.abs(dy) < 3) return;
      drag.moved = true;
      const width = over.clientWidth, height = over.clientHeight;
      if (Math.abs(dx) >= 3) {
        const shown = chart.scales.x.max - chart.scales.x.min;
        freezeAt(drag.end - dx * shown / width);
      }
      if (Math.abs(dy) >= 3) {
        for (const key of chart.yScales) {
          const [lo, hi] = drag.ranges[key];
          const shift = dy * (hi - lo) / height;
          chart.yManual[key] = [lo + shift, hi + shift];
        }
      }
      dirty = true;
    });
    const end = () => { drag = null; };
    over.addEventListener("pointerup", end);
    over.addEventListener("pointercancel", end);
  }

  function zoomY(chart, key, factor, pixelY) {
    const scale = chart.scales[key];
    if (scale.min === null || scale.max === null) return;
    const at = pixelY === undefined ? (scale.min + scale.max) / 2 : chart.posToVal(pixelY, key);
    chart.yManual[key] = [at - (at - scale.min) * factor, at + (scale.max - at) * factor];
    dirty = true;
  }
  // For scripts and tests: zoom chart ``index``'s ``key`` axis by ``factor`` (below 1: in) about its middle.
  page.zoomY = (index, key, factor) => { zoomY(charts[index], key || "y", factor); draw(); };

  function resetZoom() {
    for (const chart of charts) chart.yManual = {};
    dirty = true;
  }

  // -- the window shown: live, or frozen at an end time -----------------------------------------------
  function shownEnd() { return view.live ? latestEnd() : view.end; }
  function latestEnd() { return data.t.length ? data.t[data.t.length - 1] : 0; }

  function freezeAt(end) {
    const first = data.t.length ? data.t[0] : 0;
    view.end = Math.max(Math.min(first + windowS, latestEnd()), Math.min(end, latestEnd()));
    if (view.live) { view.live = false; showFrozen(); }
    scrubRange();
    dirty = true;
  }

  function goLive() {
    view.live = true;
    showFrozen();
    dirty = true;
  }

  function showFrozen() {
    document.querySelector(".plots").classList.toggle("frozen", !view.live);
    $("freeze").classList.toggle("on", !view.live);
    $("freeze").textContent = view.live ? "Pause plots" : "Plots paused";
    $("live").disabled = view.live;
  }

  function scrubRange() {
    const slider = $("scrub");
    const first = data.t.length ? data.t[0] : 0, last = latestEnd();
    slider.min = Math.min(first + windowS, last);
    slider.max = last;
    slider.value = shownEnd();
    $("scrub-label").textContent = view.live ? "live: newest " + windowS + " s"
      : "paused at t = " + view.end.toFixed(2) + " s (" + (last - view.end).toFixed(1) + " s behind)";
  }

  function shownWindow() {
    const last = shownEnd();
    return [Math.max(0, last - windowS), Math.max(last, windowS)];
  }

  function frame() {
    if (dirty && charts.length) draw();
    requestAnimationFrame(frame);
  }

  function draw() {
    dirty = false;
    const [x0, x1] = shownWindow();
    const start = lowerBound(data.t, x0), end = lowerBound(data.t, x1 + 1e-9);
    const t = data.t.slice(start, end);
    for (const chart of charts) {
      chart.setData([t, ...chart.keys.map((key) => data[key].slice(start, end))], false);
      chart.setScale("x", { min: x0, max: x1 });
    }
    scrubRange();
    page.draws += 1;
  }

  // -- CSV of the window shown --------------------------------------------------------------------------
  function csvOfWindow() {
    const [x0, x1] = shownWindow();
    const start = lowerBound(data.t, x0), end = lowerBound(data.t, x1 + 1e-9);
    const keys = charts.flatMap((chart) => chart.keys);
    const names = { reference: "reference", position: "position", velocity: "velocity", effort: "effort", force: "sensor force z" };
    const lines = [["time (s)"].concat(keys.map((k) => joint + " " + names[k] + " (" + units[k] + ")")).join(",")];
    for (let k = start; k < end; k++) {
      lines.push([data.t[k]].concat(keys.map((key) => (data[key][k] === null ? "" : data[key][k]))).join(","));
    }
    return lines.join("\n") + "\n";
  }
  page.csv = csvOfWindow;

  function exportCsv() {
    const [x0, x1] = shownWindow();
    const link = document.createElement("a");
    link.href = URL.createObjectURL(new Blob([csvOfWindow()], { type: "text/csv" }));
    link.download = "jointctl_" + page.hello.robot + "_" + joint + "_" + x0.toFixed(2) + "-" + x1.toFixed(2) + "s.csv";
    document.body.appendChild(link);
    link.click();
    link.remove();
    setTimeout(() => URL.revokeObjectURL(link.href), 10000);
  }

  window.addEventListener("resize", () => {
    const height = chartHeight();
    for (const chart of charts) chart.setSize({ width: chartWidth(chart.root.parentNode), height: height });
  });

  // -- gains ---------------------------------------------------------------------------------------------
  function gainId(controller, name) { return "gain-" + controller + "-" + name; }

  function sliderMax(value) {
    if (!(value > 0)) return 100;
    const magnitude = Math.pow(10, Math.ceil(Math.log10(value * 10)));
    return magnitude >= value * 4 ? magnitude : magnitude * 10;
  }

  function buildGains(groups) {
    const box = $("gains");
    box.replaceChildren();
    for (const group of groups) {
      const section = document.createElement("div");
      section.className = "gain-group";
      const title = document.createElement("h3");
      title.textContent = group.controller + " (" + group.kind + ")";
      section.appendChild(title);
      for (const gain of group.gains) section.appendChild(gainRow(group.controller, gain));
      box.appendChild(section);
    }
  }

  function gainRow(controller, gain) {
    const id = gainId(controller, gain.name);
    accepted[id] = gain.value;
    const row = document.createElement("div");
    row.className = "gain";
    const label = document.createElement("label");
    label.htmlFor = id;
    label.textContent = gain.name;
    const input = document.createElement("input");
    input.id = id;
    input.type = "text";
    input.inputMode = "decimal";
    input.value = gain.value;
    const slider = document.createElement("input");
    slider.id = id + "-slider";
    slider.type = "range";
    slider.min = 0;
    slider.max = sliderMax(gain.value);
    slider.step = "any";
    slider.value = gain.value;
    const unit = document.createElement("span");
    unit.className = "unit";
    unit.textContent = gain.unit;
    const submit = () => send({ type: "gain", controller: controller, name: gain.name, value: numberOrText(input.value) });
    input.addEventListener("change", submit);
    input.addEventListener("keydown", (event) => { if (event.key === "Enter") input.blur(); });
    slider.addEventListener("input", () => { input.value = Number(slider.value).toPrecision(4); });
    slider.addEventListener("change", submit);
    row.append(label, input, slider, unit);
    return row;
  }

  function restoreGainInputs() {
    for (const [id, value] of Object.entries(accepted)) {
      const input = $(id);
      if (input && document.activeElement !== input) input.value = value;
      const slider = $(id + "-slider");
      if (slider) slider.value = value;
    }
  }

  // -- measurements --------------------------------------------------------------------------------------
  const MEASURES = {
    overshoot_pct: ["overshoot", "%", 1], settling_time_s: ["settling time (2 %)", "s", 3],
    oscillation_frequency_hz: ["oscillation frequency", "Hz", 3], natural_frequency_rad_s: ["natural frequency", "rad/s", 2],
    damping_ratio: ["damping ratio", "", 3], rise_time_s: ["rise time", "s", 3], steady_state_error: ["steady-state error", "", 4],
    frequency_hz: ["frequency", "Hz", 3], amplitude_ratio: ["amplitude ratio", "", 3], phase_lag_deg: ["phase lag", "°", 1],
    periods_used: ["periods used", "", 0],
  };

  function showMeasure(m) {
    const source = m.source ? " · " + describeSource(m.source) + (m.source.origin === "scenario" ? ", the scenario's own" : "") : "";
    $("measure-kind").textContent = m.kind ? m.kind + (m.complete ? " (final)" : " (updating)") + source : "";
    const body = $("measure").tBodies[0];
    body.replaceChildren(...Object.entries(m.values || {}).map(([key, value]) => {
      const [label, unit, digits] = MEASURES[key] || [key, "", 3];
      const row = document.createElement("tr");
      const name = document.createElement("th");
      name.textContent = label;
      const cell = document.createElement("td");
      cell.id = "measure-" + key;
      cell.dataset.value = value === null ? "" : value;
      cell.textContent = value === null ? "not yet" : Number(value).toFixed(digits) + (unit ? " " + unit : "");
      row.append(name, cell);
      return row;
    }));
    $("measure-note").textContent = m.note || "";
  }

  // -- requests from the controls ------------------------------------------------------------------------
  function showSourceParams() {
    const type = $("source-type").value;
    for (const box of document.querySelectorAll(".params")) box.hidden = box.dataset.source !== type;
  }

  function sourceRequest() {
    const type = $("source-type").value;
    const value = (id) => numberOrText($(id).value);
    const sources = {
      hold: () => ({ type: "hold" }),
      constant: () => ({ type: "constant", value: value("constant-value") }),
      step: () => ({ type: "step", from: value("step-from"), to: value("step-to"), at: value("step-at") }),
      sine: () => ({ type: "sine", amplitude: value("sine-amplitude"), frequency_hz: value("sine-frequency"),
        offset: value("sine-offset"), rate_hz: value("sine-rate") }),
      expression: () => ({ type: "expression", expression: $("expression-text").value, rate_hz: value("expression-rate") }),
    };
    return { type: "source", controller: $("source-controller").value, source: sources[type]() };
  }

  $("source-type").addEventListener("change", showSourceParams);
  const sourceForm = $("source-apply").closest("fieldset");
  for (const kind of ["input", "change"]) {
    sourceForm.addEventListener(kind, (event) => { if (event.target.id !== "source-controller") formEdited = true; });
  }
  $("source-controller").addEventListener("change", () => { formEdited = false; fillSourceForm($("source-controller").value); });
  $("source-apply").addEventListener("click", () => send(sourceRequest()));
  for (const action of ["pause", "resume", "reset"]) $(action).addEventListener("click", () => send({ type: action }));
  $("drop").addEventListener("click", () => send({ type: "drop_weight" }));
  $("save-gains").addEventListener("click", () => send({ type: "save_gains" }));
  $("gravity-apply").addEventListener("click", () => send({ type: "gravity", value: numberOrText($("gravity").value) }));
  $("gravity-earth").addEventListener("click", () => send({ type: "gravity", value: -9.81 }));
  $("gravity-off").addEventListener("click", () => send({ type: "gravity", value: 0 }));
  // The plot switches at once (the server back-fills the new joint's window); an error switches it back.
  $("joint").addEventListener("change", () => { const name = $("joint").value; setJoint(name); send({ type: "joint", joint: name }); });
  $("window").addEventListener("change", () => { windowS = Number($("window").value); dirty = true; });
  $("freeze").addEventListener("click", () => (view.live ? freezeAt(latestEnd()) : goLive()));
  $("live").addEventListener("click", goLive);
  $("zoom-reset").addEventListener("click", resetZoom);
  $("export").addEventListener("click", exportCsv);
  $("scrub").addEventListener("input", () => freezeAt(Number($("scrub").value)));

  showSourceParams();
  connect();
  requestAnimationFrame(frame);
})();
