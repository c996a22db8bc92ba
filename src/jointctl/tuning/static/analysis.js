// jointctl tuning page: the Identify, Bode and Auto-tune panel. Each button sends one request; the
// server runs jointctl's identification tools on a simulated copy of the robot with the live gains
// (or, for Identify and Bode with "on the live robot" ticked, on the running robot itself) and
// answers "analysis" (or "error"). Apply sends the tuned gains as ordinary gain requests; Revert
// sends the gains the analysis started from.
"use strict";

(function () {
  const page = window.jointctlPage;
  const $ = (id) => document.getElementById(id);
  const KINDS = ["identify", "bode", "autotune"];
  const state = { running: null, results: {}, tuned: null, previous: null, controller: null };
  page.analysis = state;  // read by the browser tests
  let charts = [];  // the Bode panel's gain and phase

  window.addEventListener("jointctl:hello", (event) => {
    const select = $("analysis-controller");
    const names = event.detail.controllers.map((c) => c.name);
    select.replaceChildren(...names.map((name) => new Option(name, name)));
  });

  function number(id) {
    const text = String($(id).value).trim();
    const value = Number(text);
    return text !== "" && Number.isFinite(value) ? value : text;  // the server names what is wrong
  }

  function run(kind, extra) {
    state.running = kind;
    const live = Boolean(extra && extra.live);
    $("analysis-status").textContent = kind + (live ? ": running on the live robot…" : ": running on a simulated copy…");
    page.send(Object.assign({ type: kind, controller: $("analysis-controller").value }, extra || {}));
  }

  const live = () => ({ live: $("analysis-live").checked });
  $("identify").addEventListener("click", () => run("identify", live()));
  $("bode").addEventListener("click", () => run("bode", live()));
  $("autotune").addEventListener("click", () => run("autotune", {
    zeta: number("tune-zeta"), bandwidth_hz: number("tune-bandwidth"), step: number("tune-step") }));

  window.addEventListener("jointctl:analysis", (event) => {
    const m = event.detail;
    state.running = null;
    state.results[m.request] = m.result;
    $("analysis-status").textContent = m.request + " of " + m.controller + (m.live ? " (live robot)" : " (simulated copy)");
    if (m.request === "identify") showIdentify(m.result);
    if (m.request === "bode") showBode(m.result);
    if (m.request === "autotune") showAutotune(m.controller, m.result);
  });

  window.addEventListener("jointctl:error", (event) => {
    if (state.running && KINDS.includes(event.detail.request)) {
      $("analysis-status").textContent = state.running + " refused: " + event.detail.message;
      state.running = null;
    }
  });

  function fmt(value, digits) {
    return value === null || value === undefined || Number.isNaN(value) ? "–" : Number(value).toPrecision(digits || 4);
  }

  function table(rows) {
    const body = $("analysis").tBodies[0];
    body.replaceChildren(...rows.map(([name, value]) => {
      const row = document.createElement("tr");
      const th = document.createElement("th");
      th.textContent = name;
      const td = document.createElement("td");
      td.textContent = value;
      td.dataset.name = name;
      row.append(th, td);
      return row;
    }));
  }

  function withCi(result, key, unit) {
    return fmt(result[key]) + " ± " + fmt(result[key + "_ci95"], 2) + " " + unit;
  }

  function showIdentify(r) {
    $("plot-bode").hidden = true;
    const prismatic = r.joint_type === "prismatic";
    const rows = prismatic
      ? [["mass", withCi(r, "mass_kg", "kg")], ["damping", withCi(r, "damping_n_s_m", "N·s/m")],
         ["Coulomb friction", withCi(r, "friction_n", "N")], ["gravity load", withCi(r, "gravity_load_n", "N")]]
      : [["inertia", withCi(r, "inertia_kg_m2", "kg·m²")], ["damping", withCi(r, "damping_n_m_s_rad", "N·m·s/rad")],
         ["Coulomb friction", withCi(r, "friction_n_m", "N·m")],
         ["gravity sin, cos", fmt(r.gravity_sin_n_m) + ", " + fmt(r.gravity_cos_n_m) + " N·m"]];
    rows.push(["fit R²", fmt(r.r_squared, 6)]);
    for (const warning of r.warnings || []) rows.push(["warning", warning]);  // a doubtful fit says why
    table(rows);
  }

  // The Bode panel: gain and phase against a log frequency axis over the sweep's band (the reply's
  // curves.band_hz: the swept frequencies, widened to show the margins' crossings when near). Points:
  // measured; solid: the loop model's closed loop; dashed: its open loop, with the gain margin (at the
  // open loop's -180° crossing) and the phase margin (at its 0 dB crossing) drawn as bars.
  function hz(value) { return value === null || value === undefined || !Number.isFinite(value) ? null : value; }

  function showBode(r) {
    const m = r.model || {};
    const margin = (value, unit, at) => (value === null || value === undefined ? "∞ (no crossing)" : fmt(value, 3) + " " + unit) +
      (hz(at) !== null ? " at " + fmt(at, 3) + " Hz" : "");
    table([["bandwidth (-3 dB)", fmt(r.bandwidth_hz) + " Hz"],
           ["resonance", fmt(r.resonance_peak_db, 3) + " dB at " + fmt(r.resonance_hz) + " Hz"],
           ["phase -90° at", fmt(r.phase_minus_90_hz) + " Hz"],
           ["gain margin", margin(m.gain_margin_db, "dB", m.phase_crossover_hz)],
           ["phase margin", margin(m.phase_margin_deg, "°", m.gain_crossover_hz)],
           ["swept", fmt(r.frequencies_hz[0], 3) + " to " + fmt(r.frequencies_hz[r.frequencies_hz.length - 1], 3) + " Hz, " +
            r.frequencies_hz.length + " frequencies"]]);
    const box = $("plot-bode");
    box.hidden = false;
    for (const c of charts) c.destroy();
    const curves = r.curves;
    const band = curves ? curves.band_hz : [r.frequencies_hz[0], r.frequencies_hz[r.frequencies_hz.length - 1]];
    // One x array for points and curves (uPlot draws aligned columns): the union, gaps spanned.
    const measured = [r.frequencies_hz, r.gain_db, r.phase_deg];
    const modelled = curves ? [curves.frequencies_hz, curves.closed_gain_db, curves.closed_phase_deg, curves.loop_gain_db,
                               curves.loop_phase_deg] : [r.frequencies_hz, m.gain_db, m.phase_deg, [], []];
    const joined = uPlot.join([measured, modelled]);
    const [f, gain, phase, closedGain, closedPhase, loopGain, loopPhase] = joined;
    const width = Math.max(200, box.clientWidth || 400);
    const gc = hz(m.gain_crossover_hz), pc = hz(m.phase_crossover_hz);
    const marks = (kind) => (u) => {
      const ctx = u.ctx, x = (v) => u.valToPos(v, "x", true), y = (v) => u.valToPos(v, "y", true);
      const top = u.bbox.top, bottom = u.bbox.top + u.bbox.height, left = u.bbox.left, right = u.bbox.left + u.bbox.width;
      ctx.save();
      ctx.lineWidth = 1;
      ctx.setLineDash([4, 3]);
      ctx.strokeStyle = "#888";
      const level = kind === "gain" ? 0 : -180;  // the open loop's reference line
      if (u.scales.y.min <= level && level <= u.scales.y.max) { ctx.beginPath(); ctx.moveTo(left, y(level)); ctx.lineTo(right, y(level)); ctx.stroke(); }
      ctx.setLineDash([]);
      ctx.lineWidth = 2.5;
      ctx.font = "11px system-ui, sans-serif";
      const bar = (at, from, to, color, text) => {
        if (at === null || at < band[0] || at > band[1] || from === null || to === null) return;
        ctx.strokeStyle = ctx.fillStyle = color;
        ctx.beginPath(); ctx.moveTo(x(at), Math.min(bottom, Math.max(top, y(from))));
        ctx.lineTo(x(at), Math.min(bottom, Math.max(top, y(to)))); ctx.stroke();
        ctx.fillText(text, Math.min(x(at) + 4, right - 70), Math.min(bottom - 4, Math.max(top + 12, (y(from) + y(to)) / 2)));
      };
      if (kind === "gain" && Number.isFinite(m.gain_margin_db)) bar(pc, -m.gain_margin_db, 0, "#2e7d32", "GM " + fmt(m.gain_margin_db, 3) + " dB");
      if (kind === "phase" && Number.isFinite(m.phase_margin_deg)) bar(gc, -180, m.phase_margin_deg - 180, "#c62828", "PM " + fmt(m.phase_margin_deg, 3) + "°");
      ctx.restore();
    };
    const spec = (kind, title, unit, series) => ({
      width: width, height: 150, title: title,
      scales: { x: { time: false, distr: 3, range: () => band.slice() } },
      axes: [{ label: kind === "phase" ? "frequency (Hz)" : "", size: kind === "phase" ? 40 : 26 }, { label: unit, size: 50 }],
      legend: { show: kind === "gain" },
      cursor: { sync: { key: "jointctl-bode" } },
      series: [{ label: "Hz" }].concat(series),
      hooks: { draw: [marks(kind)] },
    });
    const pointsStyle = (label) => ({ label: label, stroke: "#1565c0", paths: () => null, points: { show: true, size: 6, fill: "#1565c0" } });
    const closed = { label: "model", stroke: "#ef6c00", width: 1.5, spanGaps: true };
    const open = { label: "open loop", stroke: "#6d4c41", width: 1.2, dash: [6, 4], spanGaps: true };
    charts = [
      new uPlot(spec("gain", "gain (dB)", "dB", [pointsStyle("measured"), closed, open]), [f, gain, closedGain, loopGain], $("plot-bode-gain")),
      new uPlot(spec("phase", "phase (°)", "deg", [pointsStyle("measured"), closed, open]), [f, phase, closedPhase, loopPhase], $("plot-bode-phase")),
    ];
    page.bodeCharts = charts;
    page.bodeDrawn = (page.bodeDrawn || 0) + 1;
  }

  function showAutotune(controller, r) {
    $("plot-bode").hidden = true;
    state.tuned = { controller: controller, gains: r.gains };
    state.previous = { controller: controller, gains: r.previous_gains };
    const robot = r.robot || {};
    table([["p, i, d", [r.gains.p, r.gains.i, r.gains.d].map((g) => fmt(g)).join(", ")],
           ["model: overshoot, bandwidth", fmt(r.model.overshoot_pct, 3) + " %, " + fmt(r.model.bandwidth_hz) + " Hz"],
           ["robot: overshoot, bandwidth", fmt(robot.step_overshoot_pct, 3) + " %, " + fmt(robot.bandwidth_hz) + " Hz"],
           ["was p, i, d", [r.previous_gains.p, r.previous_gains.i, r.previous_gains.d].map((g) => fmt(g)).join(", ")]]);
    $("tune-apply").disabled = false;
  }

  function sendGains(set) {
    for (const name of ["p", "i", "d"]) {
      const input = $("gain-" + set.controller + "-" + name);
      if (input) input.value = set.gains[name];
      page.send({ type: "gain", controller: set.controller, name: name, value: set.gains[name] });
    }
  }

  $("tune-apply").addEventListener("click", () => {
    if (!state.tuned) return;
    sendGains(state.tuned);
    $("tune-revert").disabled = false;
    $("analysis-status").textContent = "applied the tuned gains to " + state.tuned.controller;
  });
  $("tune-revert").addEventListener("click", () => {
    if (!state.previous) return;
    sendGains(state.previous);
    $("analysis-status").textContent = "reverted " + state.previous.controller + " to its earlier gains";
  });
})();
