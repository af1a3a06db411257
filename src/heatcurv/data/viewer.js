// heatcurv view: draws the page's data block (written by heatcurv.view) as WebGL points.
// No library, no network: the data are base64 arrays in the JSON block of the page.
"use strict";
(function () {
  const $ = (id) => document.getElementById(id);
  const status = (text) => { document.body.dataset.status = text; };

  function fail(message) {
    const box = $("error");
    box.textContent = message;
    box.style.display = "block";
    status("error: " + message);
  }
  window.addEventListener("error", (event) => fail("The view stopped: " + event.message));

  function bytes(text) {
    const raw = atob(text);
    const out = new Uint8Array(raw.length);
    for (let i = 0; i < raw.length; i++) out[i] = raw.charCodeAt(i);
    return out;
  }

  // a packed float array: {data: base64 float32 little endian, exponent: e}, values = stored * 2^e
  function floats(packed) {
    const raw = bytes(packed.data);
    return { values: new Float32Array(raw.buffer, 0, raw.length / 4), scale: Math.pow(2, packed.exponent) };
  }

  function hexColour(hex) {
    return [1, 3, 5].map((k) => parseInt(hex.slice(k, k + 2), 16));
  }

  function format(value) {
    if (value === 0) return "0";
    const text = Number(value.toPrecision(4)).toString();
    return text.replace("e+", "e");
  }

  const block = document.querySelector('script[type="application/json"]');
  let data;
  try {
    data = JSON.parse(block.textContent);
  } catch (error) {
    fail("The view's data are damaged: " + error.message);
    return;
  }

  const n = data.count;
  const positions = floats(data.positions);
  const unitPositions = new Float32Array(3 * n);  // offsets from the centre, the farthest point at distance 1
  const toUnit = positions.scale / data.radius;
  for (let i = 0; i < 3 * n; i++) unitPositions[i] = positions.values[i] * toUnit;
  const normals = data.normals ? new Int8Array(bytes(data.normals).buffer) : null;
  const reliable = data.reliable ? bytes(data.reliable) : null;
  const tables = { signed: bytes(data.colours.signed), sequential: bytes(data.colours.sequential) };
  const maskColours = data.colours.mask.map(hexColour);
  const missing = hexColour(data.colours.missing);
  const fields = new Map(data.fields.map((f) => [f.name, f]));

  // ---- the page around the picture
  $("title").textContent = data.title;
  document.title = data.title;
  for (const line of data.notes) {
    const p = document.createElement("p");
    p.textContent = line;
    $("notes").appendChild(p);
  }
  const select = $("field");
  for (const f of data.fields) {
    const option = document.createElement("option");
    option.value = f.name;
    option.textContent = f.label === f.name ? f.name : f.name + ": " + f.label;
    select.appendChild(option);
  }
  $("unreliable-row").style.display = reliable ? "" : "none";
  $("mask-no").style.background = data.colours.mask[0];
  $("mask-yes").style.background = data.colours.mask[1];
  $("missing-swatch").style.background = data.colours.missing;

  let current = fields.get(data.field);
  try {
    const asked = new URLSearchParams(window.location.hash.slice(1)).get("field");
    if (asked !== null && fields.has(asked)) current = fields.get(asked);
    else if (asked !== null) $("notes").appendChild(Object.assign(document.createElement("p"),
      { textContent: "This view has no field \u201c" + asked + "\u201d; showing " + current.name + "." }));
  } catch (error) { /* an address the browser cannot parse: the default field */ }
  select.value = current.name;

  // ---- colours
  function valueOf(f) {
    if (f.axis !== undefined) {
      const a = f.axis, s = positions.scale, c = data.centre[a], p = positions.values;
      return (i) => p[3 * i + a] * s + c;
    }
    if (!f.decoded) f.decoded = floats(f.values);
    const v = f.decoded.values, s = f.decoded.scale;
    return (i) => v[i] * s;
  }

  // where a value falls on the colour bar, 0..1: zero at the middle of a signed field's bar
  function place(f) {
    const low = f.low, high = f.high;
    if (f.kind === "signed" && low < 0 && high > 0) return (v) => (v < 0 ? 0.5 - 0.5 * v / low : 0.5 + 0.5 * v / high);
    return (v) => (v - low) / (high - low);
  }

  const colours = new Uint8Array(4 * n);
  function colourise() {
    const f = current;
    const mode = $("unreliable").value;
    const greyed = reliable !== null && f.grey;
    const value = valueOf(f);
    const table = tables[f.kind];
    const where = f.kind === "signed" || f.kind === "sequential" ? place(f) : null;
    for (let i = 0; i < n; i++) {
      const o = 4 * i;
      const v = value(i);
      let colour = null, hidden = false;
      if (greyed && reliable[i] === 0 && mode !== "coloured") {
        hidden = mode === "hidden";
        colour = missing;
      } else if (!Number.isFinite(v) || f.kind === "none") {
        colour = missing;
      } else if (f.kind === "mask") {
        colour = maskColours[v >= 0.5 ? 1 : 0];
      }
      if (colour !== null) {
        colours[o] = colour[0]; colours[o + 1] = colour[1]; colours[o + 2] = colour[2];
      } else {
        const t = where(v);
        const j = 3 * Math.round(255 * (t < 0 ? 0 : t > 1 ? 1 : t));
        colours[o] = table[j]; colours[o + 1] = table[j + 1]; colours[o + 2] = table[j + 2];
      }
      colours[o + 3] = hidden ? 0 : 255;
    }
  }

  function legend() {
    const f = current;
    const bar = f.kind === "signed" || f.kind === "sequential";
    $("label").textContent = f.kind === "none" ? f.label + ": no finite value" : f.label;
    $("bar").style.display = bar ? "block" : "none";
    $("ticks").style.display = bar ? "flex" : "none";
    $("mask").style.display = f.kind === "mask" ? "flex" : "none";
    $("missing-text").textContent = reliable !== null && f.grey ? "no value, or unreliable" : "no value";
    $("unreliable").disabled = !(reliable !== null && f.grey);
    if (!bar) return;
    const canvas = $("bar"), context = canvas.getContext("2d");
    const image = context.createImageData(canvas.width, canvas.height);
    const table = tables[f.kind];
    for (let x = 0; x < canvas.width; x++) {
      const j = 3 * Math.round(255 * x / (canvas.width - 1));
      for (let y = 0; y < canvas.height; y++) {
        const o = 4 * (y * canvas.width + x);
        image.data[o] = table[j]; image.data[o + 1] = table[j + 1]; image.data[o + 2] = table[j + 2];
        image.data[o + 3] = 255;
      }
    }
    context.putImageData(image, 0, 0);
    // values beyond the limits take the end colours (the limits are robust percentiles)
    $("low").textContent = "\u2264 " + format(f.low);
    $("high").textContent = "\u2265 " + format(f.high);
    const signed = f.kind === "signed" && f.low < 0 && f.high > 0;
    $("middle").textContent = signed ? "0" : format((f.low + f.high) / 2);
  }

  // ---- WebGL
  const canvas = $("view");
  const gl = canvas.getContext("webgl", { antialias: false, preserveDrawingBuffer: true }) ||
    canvas.getContext("experimental-webgl", { antialias: false, preserveDrawingBuffer: true });
  if (!gl) {
    fail("This browser cannot draw with WebGL (it may be switched off in its settings); the view needs it.");
    return;
  }

  const vertexSource = `
    attribute vec3 position;
    attribute vec4 colour;
    attribute vec3 normal;
    uniform mat3 rotation;
    uniform vec2 scale;
    uniform vec2 pan;
    uniform float pointSize;
    uniform float shaded;
    varying vec4 vColour;
    varying float vShade;
    void main() {
      vec3 p = rotation * position;  // x right, y up, z towards the camera
      gl_Position = vec4(p.x * scale.x + pan.x, p.y * scale.y + pan.y, -0.5 * p.z, 1.0);
      gl_PointSize = pointSize;
      vShade = 1.0;
      float len = length(normal);
      if (shaded > 0.5 && len > 0.5) vShade = 0.3 + 0.7 * abs((rotation * normal).z) / len;
      vColour = colour;
    }`;
  const fragmentSource = `
    precision mediump float;
    varying vec4 vColour;
    varying float vShade;
    void main() {
      if (vColour.a < 0.5) discard;
      vec2 c = 2.0 * gl_PointCoord - 1.0;
      if (dot(c, c) > 1.0) discard;
      gl_FragColor = vec4(vColour.rgb * vShade, 1.0);
    }`;

  function shader(type, source) {
    const s = gl.createShader(type);
    gl.shaderSource(s, source);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error("shader: " + gl.getShaderInfoLog(s));
    return s;
  }
  // every WebGL object of the picture; made again when the browser restores a lost context
  // (a graphics driver reset, too many pages with WebGL, a software renderer restarting)
  let colourBuffer, uRotation, uScale, uPan, uPointSize, largestPoint;
  function setUp() {
    const program = gl.createProgram();
    gl.attachShader(program, shader(gl.VERTEX_SHADER, vertexSource));
    gl.attachShader(program, shader(gl.FRAGMENT_SHADER, fragmentSource));
    gl.linkProgram(program);
    if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error("program: " + gl.getProgramInfoLog(program));
    gl.useProgram(program);

    function attribute(name, array, size, type, normalised) {
      const location = gl.getAttribLocation(program, name);
      const buffer = gl.createBuffer();
      gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
      gl.bufferData(gl.ARRAY_BUFFER, array, gl.STATIC_DRAW);
      gl.enableVertexAttribArray(location);
      gl.vertexAttribPointer(location, size, type, normalised, 0, 0);
      return buffer;
    }
    attribute("position", unitPositions, 3, gl.FLOAT, false);
    colourBuffer = attribute("colour", colours, 4, gl.UNSIGNED_BYTE, true);
    if (normals) {
      attribute("normal", normals, 3, gl.BYTE, true);
    } else {
      const location = gl.getAttribLocation(program, "normal");
      gl.disableVertexAttribArray(location);
      gl.vertexAttrib3f(location, 0, 0, 0);
    }
    const uniform = (name) => gl.getUniformLocation(program, name);
    uRotation = uniform("rotation");
    uScale = uniform("scale");
    uPan = uniform("pan");
    uPointSize = uniform("pointSize");
    gl.uniform1f(uniform("shaded"), normals ? 1 : 0);
    gl.enable(gl.DEPTH_TEST);
    gl.depthFunc(gl.LESS);
    largestPoint = gl.getParameter(gl.ALIASED_POINT_SIZE_RANGE)[1];
  }
  setUp();
  canvas.addEventListener("webglcontextlost", (event) => {
    event.preventDefault();  // asks the browser to restore it
    status("lost the WebGL context; waiting for the browser to restore it");
  });
  canvas.addEventListener("webglcontextrestored", () => {
    setUp();
    show(current.name);
  });

  // ---- camera: rows of `rotation` are screen right, up and towards the camera
  let rotation, zoom, pan;
  function firstView() {
    rotation = data.frame.map((row) => row.slice());
    zoom = 1;
    pan = [0, 0];
  }
  firstView();

  function multiply(a, b) {
    return a.map((row) => [0, 1, 2].map((j) => row[0] * b[0][j] + row[1] * b[1][j] + row[2] * b[2][j]));
  }
  function orthonormal(m) {  // Gram-Schmidt on the rows: many small turns drift
    const norm = (v) => { const l = Math.hypot(v[0], v[1], v[2]); return v.map((x) => x / l); };
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    const r = norm(m[0]);
    const u = norm(m[1].map((x, k) => x - dot(m[1], r) * r[k]));
    const t = [r[1] * u[2] - r[2] * u[1], r[2] * u[0] - r[0] * u[2], r[0] * u[1] - r[1] * u[0]];
    return [r, u, t];
  }
  function turn(dx, dy) {  // dragging right turns the near side right, dragging down turns it down
    const k = Math.PI / Math.min(canvas.clientWidth, canvas.clientHeight);
    const a = dx * k, b = dy * k;
    const aboutUp = [[Math.cos(a), 0, Math.sin(a)], [0, 1, 0], [-Math.sin(a), 0, Math.cos(a)]];
    const aboutRight = [[1, 0, 0], [0, Math.cos(b), -Math.sin(b)], [0, Math.sin(b), Math.cos(b)]];
    rotation = orthonormal(multiply(multiply(aboutRight, aboutUp), rotation));
  }

  let frames = 0, lift = 0;
  function draw() {
    if (gl.isContextLost()) return;
    const ratio = window.devicePixelRatio || 1;
    const width = Math.max(1, Math.round(canvas.clientWidth * ratio));
    const height = Math.max(1, Math.round(canvas.clientHeight * ratio));
    if (canvas.width !== width || canvas.height !== height) {
      canvas.width = width;
      canvas.height = height;
    }
    // the cloud fills the view above the colour bar: device pixels per unit, and the shift up of its middle
    const reserved = Math.min(Math.round(($("legend").offsetHeight + 20) * ratio), height / 2);
    const pixels = zoom * 0.92 * Math.min(width, height - reserved) / 2;
    lift = reserved / height;
    const r = rotation;
    gl.viewport(0, 0, width, height);
    gl.clearColor(1, 1, 1, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.uniformMatrix3fv(uRotation, false, new Float32Array([
      r[0][0], r[1][0], r[2][0], r[0][1], r[1][1], r[2][1], r[0][2], r[1][2], r[2][2]]));
    gl.uniform2f(uScale, 2 * pixels / width, 2 * pixels / height);
    gl.uniform2f(uPan, pan[0], pan[1] + lift);
    const size = data.disc / data.radius * pixels * Math.pow(2, Number($("size").value));
    gl.uniform1f(uPointSize, Math.min(Math.max(size, 1), largestPoint));
    gl.drawArrays(gl.POINTS, 0, n);
    frames += 1;
    document.body.dataset.frames = String(frames);  // pictures drawn so far: a test can wait for the next
  }

  let pending = false;
  function redraw() {
    if (pending) return;
    pending = true;
    window.requestAnimationFrame(() => { pending = false; draw(); });
  }

  function show(name) {
    current = fields.get(name);
    colourise();
    legend();
    if (gl.isContextLost()) return;  // drawn when the context is restored
    gl.bindBuffer(gl.ARRAY_BUFFER, colourBuffer);
    gl.bufferSubData(gl.ARRAY_BUFFER, 0, colours);
    draw();
    status("drawn " + n + " points, field " + current.name);
  }

  // ---- mouse, touch and keys
  let drag = null;
  canvas.addEventListener("pointerdown", (event) => {
    drag = { x: event.clientX, y: event.clientY, move: event.shiftKey || event.button !== 0 };
    canvas.setPointerCapture(event.pointerId);
    canvas.classList.add("dragging");
  });
  canvas.addEventListener("pointermove", (event) => {
    if (!drag) return;
    const dx = event.clientX - drag.x, dy = event.clientY - drag.y;
    drag.x = event.clientX;
    drag.y = event.clientY;
    if (drag.move) {
      pan[0] += 2 * dx / canvas.clientWidth;
      pan[1] -= 2 * dy / canvas.clientHeight;
    } else {
      turn(dx, dy);
    }
    redraw();
  });
  const release = () => { drag = null; canvas.classList.remove("dragging"); };
  canvas.addEventListener("pointerup", release);
  canvas.addEventListener("pointercancel", release);
  canvas.addEventListener("contextmenu", (event) => event.preventDefault());
  canvas.addEventListener("wheel", (event) => {  // zoom about the pointer
    event.preventDefault();
    const step = event.deltaMode === 1 ? 33 : event.deltaMode === 2 ? 400 : 1;
    const factor = Math.exp(-event.deltaY * step * 0.0015);
    const box = canvas.getBoundingClientRect();
    const cx = 2 * (event.clientX - box.left) / box.width - 1, cy = 1 - 2 * (event.clientY - box.top) / box.height;
    pan = [cx - (cx - pan[0]) * factor, cy - lift - (cy - lift - pan[1]) * factor];
    zoom *= factor;
    redraw();
  }, { passive: false });
  canvas.addEventListener("dblclick", () => { firstView(); redraw(); });
  window.addEventListener("keydown", (event) => {
    if ((event.key === "r" || event.key === "R") && event.target.tagName !== "SELECT") { firstView(); redraw(); }
  });
  window.addEventListener("resize", redraw);
  select.addEventListener("change", () => {
    show(select.value);
    try {
      window.history.replaceState(null, "", "#field=" + encodeURIComponent(select.value));
    } catch (error) { /* some browsers refuse it for local files: the address keeps its field */ }
  });
  $("unreliable").addEventListener("change", () => show(current.name));
  $("size").addEventListener("input", redraw);

  show(current.name);
})();
