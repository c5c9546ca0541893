// rsasim scene viewer: draws the scene JSON of the page on a 2D canvas. Orthographic view,
// painter's algorithm (every primitive sorted by depth each frame), mouse drag turns the scene,
// the wheel zooms, a double click resets. No libraries, no network.
(function () {
  "use strict";
  var scene = JSON.parse(document.getElementById("scene-data").textContent);
  var canvas = document.getElementById("view");
  var ctx = canvas.getContext("2d");
  var WIDTH = 900, HEIGHT = 640;
  var dpr = window.devicePixelRatio || 1;
  canvas.width = Math.round(WIDTH * dpr);
  canvas.height = Math.round(HEIGHT * dpr);
  var C = {
    source: "#d62728", detector: "#1f77b4", cone: "#f5d76e", coneLine: "#c9a227",
    envelope: "#b07be0", bead: "#222222", plate: "#7f8c99", cylinder: "#9aa6b2",
    warn: "#ff7f0e", text: "#111111"
  };
  var MESH_RGB = [154, 166, 178];

  // Every primitive in world (scanner) coordinates, built once.
  var prims = [];
  var all = [];
  function add(p) { prims.push(p); p.p.forEach(function (q) { all.push(q); }); }
  function poly(points, fill, alpha, layer) { add({ t: "poly", p: points, fill: fill, alpha: alpha, layer: layer || "" }); }
  function line(a, b, color, alpha, width, dash, layer) {
    add({ t: "line", p: [a, b], color: color, alpha: alpha, width: width || 1, dash: dash || null, layer: layer || "" });
  }
  function boxCorners(lo, hi) {
    var out = [];
    for (var k = 0; k < 8; k++) {
      out.push([(k & 1) ? hi[0] : lo[0], (k & 2) ? hi[1] : lo[1], (k & 4) ? hi[2] : lo[2]]);
    }
    return out;
  }
  // Corner k of a box at (±x, ±y, ±z) by the bits of k: its 6 faces and 12 edges.
  function box(corners, fill, alpha, edgeAlpha, dash, layer) {
    for (var bit = 0; bit < 3; bit++) {
      var o1 = 1 << ((bit + 1) % 3), o2 = 1 << ((bit + 2) % 3);
      for (var side = 0; side < 2; side++) {
        var base = side ? (1 << bit) : 0;
        poly([corners[base], corners[base | o1], corners[base | o1 | o2], corners[base | o2]], fill, alpha, layer);
      }
    }
    for (var k = 0; k < 8; k++) {
      for (var b = 0; b < 3; b++) {
        var j = k | (1 << b);
        if (j !== k) { line(corners[k], corners[j], fill, edgeAlpha, 1, dash, layer); }
      }
    }
  }
  function mean(points) {
    var m = [0, 0, 0];
    points.forEach(function (p) { m[0] += p[0]; m[1] += p[1]; m[2] += p[2]; });
    return [m[0] / points.length, m[1] / points.length, m[2] / points.length];
  }

  var labels = [];
  var sourceById = {};
  scene.sources.forEach(function (s) {
    sourceById[s.id] = s.position;
    add({ t: "dot", p: [s.position], px: 5, color: C.source, layer: "" });
    labels.push({ p: s.position, text: s.id, color: C.source });
    if (s.envelope) { box(boxCorners(s.envelope[0], s.envelope[1]), C.envelope, 0.12, 0.7, [4, 3], "env"); }
  });
  scene.detectors.forEach(function (d) {
    var c = d.corners;
    poly(c, C.detector, 0.35, "");
    for (var k = 0; k < 4; k++) { line(c[k], c[(k + 1) % 4], C.detector, 1, k === 0 ? 3 : 1.2, null, ""); }
    labels.push({ p: mean(c), text: d.id, color: C.detector });
    if (d.envelope) { box(boxCorners(d.envelope[0], d.envelope[1]), C.envelope, 0.08, 0.6, [4, 3], "env"); }
    var s = sourceById[d.source];
    if (s) {
      for (var i = 0; i < 4; i++) {
        poly([s, c[i], c[(i + 1) % 4]], C.cone, 0.10, "cone");
        line(s, c[i], C.coneLine, 0.6, 1, null, "cone");
      }
    }
  });
  scene.phantoms.forEach(function (ph) {
    ph.cuboids.forEach(function (q) { box(q, C.plate, 0.18, 0.8, null, ""); });
    ph.cylinders.forEach(function (rings) {
      var a = rings[0], b = rings[1], n = a.length;
      for (var i = 0; i < n; i++) {
        var j = (i + 1) % n;
        poly([a[i], a[j], b[j], b[i]], C.cylinder, 0.12, "");
        line(a[i], a[j], C.cylinder, 0.9, 1, null, "");
        line(b[i], b[j], C.cylinder, 0.9, 1, null, "");
        if (i % 8 === 0) { line(a[i], b[i], C.cylinder, 0.9, 1, null, ""); }
      }
    });
    if (ph.mesh) {
      var v = ph.mesh.vertices, t = ph.mesh.triangles;
      var at = function (i) { return [v[3 * i], v[3 * i + 1], v[3 * i + 2]]; };
      for (var k = 0; k + 2 < t.length; k += 3) {
        add({ t: "tri", p: [at(t[k]), at(t[k + 1]), at(t[k + 2])], layer: "" });
      }
    }
    ph.beads.forEach(function (b) {
      add({ t: "dot", p: [[b[0], b[1], b[2]]], r: b[3], px: 1.5, color: C.bead, layer: "" });
    });
    labels.push({ p: ph.centre, text: ph.id, color: C.text });
    if (ph.envelope) { box(boxCorners(ph.envelope[0], ph.envelope[1]), C.envelope, 0.10, 0.7, [4, 3], "env"); }
  });
  // Warnings at the same place stand side by side.
  var warnings = [], atPlace = {};
  scene.warnings.forEach(function (w, i) {
    if (!w.at) { return; }
    var key = w.at.join(",");
    atPlace[key] = (atPlace[key] || 0) + 1;
    warnings.push({ p: w.at, n: i + 1, shift: 20 * (atPlace[key] - 1) });
  });

  // The view: centre and radius of everything; yaw about the scanner y axis, then pitch.
  var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  all.forEach(function (p) {
    for (var k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], p[k]); hi[k] = Math.max(hi[k], p[k]); }
  });
  if (!all.length) { lo = [-1, -1, -1]; hi = [1, 1, 1]; }
  var centre = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
  var radius = Math.max(1e-6, Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) / 2);
  var HOME = { yaw: -0.75, pitch: 0.4, zoom: 1 };
  var view = { yaw: HOME.yaw, pitch: HOME.pitch, zoom: HOME.zoom };

  function show(layer) {
    if (layer === "cone") { return document.getElementById("show-cones").checked; }
    if (layer === "env") { return document.getElementById("show-envelopes").checked; }
    return true;
  }

  function draw() {
    var cy = Math.cos(view.yaw), sy = Math.sin(view.yaw);
    var cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
    var scale = view.zoom * 0.62 * Math.min(WIDTH, HEIGHT) / radius;
    function tf(p) {
      var x = p[0] - centre[0], y = p[1] - centre[1], z = p[2] - centre[2];
      var x1 = cy * x + sy * z, z1 = -sy * x + cy * z;
      var y2 = cp * y - sp * z1, z2 = sp * y + cp * z1;
      return [WIDTH / 2 + x1 * scale, HEIGHT / 2 - y2 * scale, z2];
    }
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
    ctx.clearRect(0, 0, WIDTH, HEIGHT);
    ctx.fillStyle = "#fbfbfb";
    ctx.fillRect(0, 0, WIDTH, HEIGHT);
    var list = [];
    prims.forEach(function (pr) {
      if (!show(pr.layer)) { return; }
      var q = pr.p.map(tf);
      var depth = 0;
      q.forEach(function (a) { depth += a[2]; });
      list.push({ pr: pr, q: q, depth: depth / q.length });
    });
    list.sort(function (a, b) { return a.depth - b.depth; });
    list.forEach(function (it) {
      var pr = it.pr, q = it.q;
      ctx.setLineDash([]);
      if (pr.t === "poly" || pr.t === "tri") {
        ctx.beginPath();
        ctx.moveTo(q[0][0], q[0][1]);
        for (var i = 1; i < q.length; i++) { ctx.lineTo(q[i][0], q[i][1]); }
        ctx.closePath();
        if (pr.t === "tri") {
          // Flat shading: light from the viewer.
          var ux = q[1][0] - q[0][0], uy = q[1][1] - q[0][1], uz = q[1][2] - q[0][2];
          var vx = q[2][0] - q[0][0], vy = q[2][1] - q[0][1], vz = q[2][2] - q[0][2];
          var nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
          var len = Math.hypot(nx, ny, nz) || 1;
          var shade = 0.35 + 0.65 * Math.abs(nz) / len;
          ctx.globalAlpha = 1;
          ctx.fillStyle = "rgb(" + MESH_RGB.map(function (c) { return Math.round(c * shade); }).join(",") + ")";
          ctx.fill();
          ctx.strokeStyle = ctx.fillStyle;
          ctx.lineWidth = 0.5;
          ctx.stroke();
        } else {
          ctx.globalAlpha = pr.alpha;
          ctx.fillStyle = pr.fill;
          ctx.fill();
        }
      } else if (pr.t === "line") {
        ctx.globalAlpha = pr.alpha;
        ctx.strokeStyle = pr.color;
        ctx.lineWidth = pr.width;
        if (pr.dash) { ctx.setLineDash(pr.dash); }
        ctx.beginPath();
        ctx.moveTo(q[0][0], q[0][1]);
        ctx.lineTo(q[1][0], q[1][1]);
        ctx.stroke();
      } else if (pr.t === "dot") {
        ctx.globalAlpha = 1;
        ctx.fillStyle = pr.color;
        ctx.beginPath();
        ctx.arc(q[0][0], q[0][1], Math.max(pr.px, (pr.r || 0) * scale), 0, 2 * Math.PI);
        ctx.fill();
      }
    });
    ctx.globalAlpha = 1;
    ctx.setLineDash([]);
    ctx.font = "12px Helvetica, Arial, sans-serif";
    if (document.getElementById("show-labels").checked) {
      labels.forEach(function (l) {
        var q = tf(l.p);
        ctx.fillStyle = "rgba(255,255,255,0.75)";
        var w = ctx.measureText(l.text).width;
        ctx.fillRect(q[0] + 6, q[1] - 12, w + 4, 15);
        ctx.fillStyle = l.color;
        ctx.fillText(l.text, q[0] + 8, q[1]);
      });
    }
    warnings.forEach(function (w) {
      var q = tf(w.p);
      ctx.fillStyle = C.warn;
      ctx.beginPath();
      ctx.arc(q[0] + w.shift, q[1] - 16, 9, 0, 2 * Math.PI);
      ctx.fill();
      ctx.fillStyle = "#ffffff";
      ctx.textAlign = "center";
      ctx.fillText(String(w.n), q[0] + w.shift, q[1] - 12);
      ctx.textAlign = "start";
    });
    // Axes of the scanner frame, bottom left.
    var o = [60, HEIGHT - 50];
    [["x", [1, 0, 0], "#c0392b"], ["y", [0, 1, 0], "#27ae60"], ["z", [0, 0, 1], "#2c6fbb"]].forEach(function (a) {
      var d = a[1];
      var x1 = cy * d[0] + sy * d[2], z1 = -sy * d[0] + cy * d[2];
      var y2 = cp * d[1] - sp * z1;
      ctx.strokeStyle = a[2];
      ctx.fillStyle = a[2];
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.moveTo(o[0], o[1]);
      ctx.lineTo(o[0] + 30 * x1, o[1] - 30 * y2);
      ctx.stroke();
      ctx.fillText(a[0], o[0] + 36 * x1 - 3, o[1] - 36 * y2 + 4);
    });
    return list.length;
  }

  var drag = null;
  canvas.addEventListener("mousedown", function (e) { drag = { x: e.clientX, y: e.clientY }; });
  window.addEventListener("mouseup", function () { drag = null; });
  window.addEventListener("mousemove", function (e) {
    if (!drag) { return; }
    view.yaw += (e.clientX - drag.x) * 0.01;
    view.pitch = Math.max(-1.55, Math.min(1.55, view.pitch + (e.clientY - drag.y) * 0.01));
    drag = { x: e.clientX, y: e.clientY };
    draw();
  });
  canvas.addEventListener("wheel", function (e) {
    e.preventDefault();
    view.zoom = Math.max(0.2, Math.min(50, view.zoom * Math.exp(-e.deltaY * 0.0015)));
    draw();
  }, { passive: false });
  function reset() { view.yaw = HOME.yaw; view.pitch = HOME.pitch; view.zoom = HOME.zoom; draw(); }
  canvas.addEventListener("dblclick", reset);
  document.getElementById("reset").addEventListener("click", reset);
  ["show-cones", "show-envelopes", "show-labels"].forEach(function (id) {
    document.getElementById(id).addEventListener("change", draw);
  });
  // For tests and scripts: how many primitives the first frame drew.
  document.body.setAttribute("data-drawn", String(draw()));
})();
