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
    },
    data(m) {
      if (m.joint !== joint) return;  // sent before a joint change arrived
      page.dataMessages += 1;
      append(m.t, m.series);
    },
    reset() { clearData(); },
    status(m) {
      page.status = m;
      setState(m.paused ? "paused" : "running");
      $("clock").textContent = "t = " + m.time_s.toFixed(3) + " s · " +
        (m.gravity_z_m_s2 === null ? "real hardware (no gravity or weight to set)" : "gravity " + m.gravity_z_m_s2 + " m/s²") +
        (m.weight_dropped ? " · weight dropped" : "") + (m.overruns ? " · late cycles " + m.overruns : "");
      const sources = Object.entries(m.sources).map(([c, s]) => c + ": " + describeSource(s));
      $("source-now").textContent = sources.length ? sources.join("; ") : "no source: controllers hold";
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
    const params = Object.entries(s).filter(([k]) => k !== "type").map(([k, v]) => k + " " + v);
    return s.type + (params.length ? " (" + params.join(", ") + ")" : "");
  }

  // -- plots -------------------------------------------------------------------------------------------
  function clearData() {
    for (const key of Object.keys(data)) data[key] = [];
    page.points = 0;
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
    // Keep KEEP_S seconds; drop the old part in one go now and then, not a sample at a time.
    const cut = lowerBound(data.t, page.lastTime - KEEP_S);
    if (cut > 2000) for (const key of Object.keys(data)) data[key] = data[key].slice(cut);
    dirty = true;
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
  }

  function buildCharts() {
    for (const chart of charts) chart.destroy();
    const info = page.hello.joints.find((j) => j.name === joint);
    const unit = info && info.prismatic ? "m" : "rad";
    const effortUnit = info && info.prismatic ? "N" : "N·m";
    const hasForce = page.hello.sensors.length > 0;
    const specs = [
      ["plot-position", "position (" + unit + ")", [["reference", "#d62728"], ["position", "#1f77b4"]]],
      ["plot-velocity", "velocity (" + unit + "/s)", [["velocity", "#2ca02c"]]],
      ["plot-effort", "effort (" + effortUnit + ")" + (hasForce ? ", sensor force z (N)" : ""),
        [["effort", "#9467bd"]].concat(hasForce ? [["force", "#8c564b"]] : [])],
    ];
    charts = specs.map(([id, label, lines]) => {
      const element = $(id);
      element.replaceChildren();
      const chart = new uPlot({
        width: Math.max(300, element.clientWidth), height: 190,
        scales: { x: { time: false } },
        cursor: { sync: { key: "jointctl" } },
        axes: [{ label: "loop time (s)" }, { label: label, size: 70 }],
        series: [{ label: "t" }].concat(lines.map(([name, color]) => ({ label: name, stroke: color, width: 1.5 }))),
      }, [[], ...lines.map(() => [])], element);
      chart.keys = lines.map(([name]) => name);
      return chart;
    });
    dirty = true;
  }

  function draw() {
    if (dirty && charts.length) {
      dirty = false;
      const end = data.t.length;
      const last = end ? data.t[end - 1] : 0;
      const start = lowerBound(data.t, last - windowS);
      const t = data.t.slice(start, end);
      for (const chart of charts) {
        chart.setData([t, ...chart.keys.map((key) => data[key].slice(start, end))], false);
        chart.setScale("x", { min: Math.max(0, last - windowS), max: Math.max(last, windowS) });
      }
      page.draws += 1;
    }
    requestAnimationFrame(draw);
  }

  window.addEventListener("resize", () => {
    for (const chart of charts) chart.setSize({ width: Math.max(300, chart.root.parentNode.clientWidth), height: 190 });
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
    $("measure-kind").textContent = m.kind ? m.kind + (m.complete ? " (final)" : " (updating)") : "";
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

  showSourceParams();
  connect();
  requestAnimationFrame(draw);
})();
