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
  let chart = null;

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
    table(rows);
  }

  function showBode(r) {
    table([["bandwidth (-3 dB)", fmt(r.bandwidth_hz) + " Hz"],
           ["resonance", fmt(r.resonance_peak_db, 3) + " dB at " + fmt(r.resonance_hz) + " Hz"],
           ["phase -90° at", fmt(r.phase_minus_90_hz) + " Hz"],
           ["model phase margin", fmt(r.model.phase_margin_deg, 3) + "°"],
           ["model gain margin", fmt(r.model.gain_margin_db, 3) + " dB"]]);
    const box = $("plot-bode");
    box.hidden = false;
    if (chart) chart.destroy();
    const options = {
      width: Math.max(200, box.clientWidth || 400), height: 180, title: "closed-loop gain (dB)",
      scales: { x: { time: false, distr: 3 } },
      axes: [{ label: "Hz" }, {}],
      series: [{}, { label: "measured", stroke: "#1565c0", points: { show: true } },
               { label: "model", stroke: "#ef6c00" }],
    };
    chart = new uPlot(options, [r.frequencies_hz, r.gain_db, r.model.gain_db], box);
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
