/* brdfcl's live view of a fit on its report page (brdfcl.report.view.webgl): the fragment shader
   in #brdfcl-fs (the model's generated GLSL ES and webgl_view.glsl) draws the lit sphere; the same
   shader, built with VALUES, renders linear values into an RGBA32UI target (float bits) that
   readPixels brings back for the polar slice and the exposure.  Settings in #brdfcl-view-config.
   window.brdfclView.sphere(size, theta, phi) and .slice(thetaI, n) return linear values (rows
   bottom first, as GL reads them) for checks. */
(function () {
  'use strict';
  var cfg = JSON.parse(document.getElementById('brdfcl-view-config').textContent);
  var root = document.getElementById('brdfcl-view');
  var note = document.getElementById('brdfcl-view-note');
  function off(text) {
    note.textContent = text;
    root.style.display = 'none';
  }
  var canvas = document.getElementById('brdfcl-fit');
  var gl = null;
  try {
    gl = canvas.getContext('webgl2', {antialias: false, preserveDrawingBuffer: true});
  } catch (e) {
    gl = null;
  }
  if (!gl) {
    off('WebGL 2 is not available in this browser: no live view (the static images below remain).');
    return;
  }
  var FS = document.getElementById('brdfcl-fs').textContent.replace(/^\s+/, '');
  var VS = '#version 300 es\nvoid main(void)\n{\n    vec2 p = vec2(float((gl_VertexID << 1) & 2), ' +
    'float(gl_VertexID & 2));\n    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);\n}\n';

  function build(defines) {
    var p = gl.createProgram();
    [[gl.VERTEX_SHADER, VS], [gl.FRAGMENT_SHADER, FS.replace(/^(#version[^\n]*\n)/, '$1' + defines)]]
      .forEach(function (s) {
        var sh = gl.createShader(s[0]);
        gl.shaderSource(sh, s[1]);
        gl.compileShader(sh);
        if (!gl.getShaderParameter(sh, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(sh));
        gl.attachShader(p, sh);
      });
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    return p;
  }
  var show, values;
  try {
    show = build('');
    values = build('#define VALUES\n');
  } catch (e) {
    off('The live view could not be built in this browser (' + String(e.message).split('\n')[0] +
        '); the static images below remain.');
    return;
  }

  var params = cfg.params.map(function (q) { return {q: q, value: q.value}; });
  function uniforms(p, extra) {
    gl.useProgram(p);
    params.forEach(function (q) {
      var at = gl.getUniformLocation(p, q.q.u);
      if (at) gl.uniform1f(at, q.value);
    });
    Object.keys(extra).forEach(function (k) {
      var at = gl.getUniformLocation(p, k), v = extra[k];
      if (!at) return;
      if (k === 'u_mode') gl.uniform1i(at, v);
      else if (v.length === 3) gl.uniform3fv(at, v);
      else if (v.length === 2) gl.uniform2fv(at, v);
      else gl.uniform1f(at, v);
    });
  }
  /* linear values (w x h x 4: r, g, b as floats, then a flag) of the VALUES program */
  function read(w, h, extra) {
    var tex = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32UI, w, h, 0, gl.RGBA_INTEGER, gl.UNSIGNED_INT, null);
    var fb = gl.createFramebuffer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
    gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, tex, 0);
    gl.viewport(0, 0, w, h);
    extra.u_size = [w, h];
    uniforms(values, extra);
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    var bits = new Uint32Array(w * h * 4);
    gl.readPixels(0, 0, w, h, gl.RGBA_INTEGER, gl.UNSIGNED_INT, bits);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.deleteFramebuffer(fb);
    gl.deleteTexture(tex);
    return {f: new Float32Array(bits.buffer), flag: bits};
  }
  function direction(theta, phi) {
    var t = theta * Math.PI / 180, p = phi * Math.PI / 180;
    return [Math.sin(t) * Math.cos(p), Math.sin(t) * Math.sin(p), Math.cos(t)];
  }
  function sphere(size, theta, phi) {
    return read(size, size, {u_mode: 0, u_light: direction(theta, phi)});
  }
  function slice(thetaI, n) {
    return read(n, 1, {u_mode: 1, u_theta_i: thetaI * Math.PI / 180}).f;
  }
  /* white: the configured one (the measured key-light sphere's), else the 99th percentile of
     the fit's brightest channel at the first light */
  var white = cfg.white, whiteText = cfg.white_text;
  if (!(white > 0)) {
    var v = sphere(64, cfg.light[0], cfg.light[1]), lit = [];
    for (var i = 0; i < v.f.length; i += 4) {
      var m = Math.max(v.f[i], v.f[i + 1], v.f[i + 2]);
      if (m > 0 && isFinite(m)) lit.push(m);
    }
    lit.sort(function (a, b) { return a - b; });
    white = lit.length ? lit[Math.min(lit.length - 1, Math.floor(0.99 * lit.length))] : 1;
    whiteText = 'the 99th percentile of the fit at the first light';
  }

  var el = function (id) { return document.getElementById(id); };
  var controls = {theta: el('brdfcl-theta'), phi: el('brdfcl-phi'), ti: el('brdfcl-ti'), stops: el('brdfcl-stops')};
  controls.theta.value = cfg.light[0];
  controls.phi.value = cfg.light[1];
  controls.ti.value = cfg.theta_i;
  controls.stops.value = 0;

  var sliders = el('brdfcl-params');
  params.forEach(function (q) {
    var lo = q.q.lo, hi = q.q.hi, log = q.q.log && lo > 0;
    q.to = function (u) { return log ? lo * Math.pow(hi / lo, u) : lo + (hi - lo) * u; };
    q.from = function (x) { return log ? Math.log(x / lo) / Math.log(hi / lo) : (x - lo) / (hi - lo); };
    var row = document.createElement('label');
    row.className = 'brdfcl-row';
    row.innerHTML = '<span></span><input type="range" min="0" max="1000" step="1"><output></output>';
    row.firstChild.textContent = q.q.name;
    q.input = row.children[1];
    q.out = row.children[2];
    q.reset = function () {
      q.value = q.q.value;
      q.input.value = Math.round(1000 * Math.min(1, Math.max(0, q.from(q.value))));
    };
    q.reset();
    q.input.addEventListener('input', function () { q.value = q.to(q.input.value / 1000); later(); });
    sliders.appendChild(row);
  });
  el('brdfcl-reset').addEventListener('click', function () {
    params.forEach(function (q) { q.reset(); });
    later();
  });

  var plot = el('brdfcl-slice'), ctx = plot.getContext('2d');
  var COLORS = ['#d62728', '#2ca02c', '#1f77b4'], DECADES = 6, N_SLICE = 361;
  function drawSlice(thetaI) {
    var f = slice(thetaI, N_SLICE), w = plot.width, h = plot.height;
    var cx = w / 2, cy = h - 22, R = Math.min(w / 2 - 30, h - 40);
    var top = -Infinity;
    for (var i = 0; i < f.length; i++) if ((i & 3) < 3 && f[i] > 0 && isFinite(f[i])) top = Math.max(top, f[i]);
    var hi = isFinite(top) ? Math.ceil(Math.log10(top)) : 0, lo = hi - DECADES;
    ctx.clearRect(0, 0, w, h);
    ctx.font = '11px sans-serif';
    ctx.strokeStyle = '#ccc';
    ctx.fillStyle = '#666';
    ctx.lineWidth = 1;
    for (var d = 1; d <= DECADES; d++) {
      ctx.beginPath();
      ctx.arc(cx, cy, R * d / DECADES, Math.PI, 2 * Math.PI);
      ctx.stroke();
      ctx.fillText('1e' + (lo + d), cx + R * d / DECADES - 12, cy + 12);
    }
    [-90, -60, -30, 0, 30, 60, 90].forEach(function (a) {
      var t = a * Math.PI / 180;
      ctx.beginPath();
      ctx.moveTo(cx, cy);
      ctx.lineTo(cx + R * Math.sin(t), cy - R * Math.cos(t));
      ctx.stroke();
      ctx.fillText(a + '\u00b0', cx + (R + 6) * Math.sin(t) - 10, cy - (R + 6) * Math.cos(t));
    });
    function ray(a, color, dash, text) {
      var t = a * Math.PI / 180;
      ctx.save();
      ctx.strokeStyle = color;
      ctx.setLineDash(dash);
      ctx.beginPath();
      ctx.moveTo(cx, cy);
      ctx.lineTo(cx + R * Math.sin(t), cy - R * Math.cos(t));
      ctx.stroke();
      ctx.restore();
      ctx.fillText(text, cx + 0.75 * R * Math.sin(t) + 4, cy - 0.75 * R * Math.cos(t));
    }
    ['R', 'G', 'B'].forEach(function (name, c) {
      ctx.fillStyle = COLORS[c];
      ctx.fillText(name, 10 + 14 * c, 16);
    });
    ctx.fillStyle = '#666';
    ray(-thetaI, '#e0a000', [], 'light');
    ray(thetaI, '#999', [4, 3], 'mirror');
    for (var c = 0; c < 3; c++) {
      ctx.strokeStyle = COLORS[c];
      ctx.lineWidth = 1.5;
      ctx.beginPath();
      for (var k = 0; k < N_SLICE; k++) {
        var t = ((k + 0.5) / N_SLICE * 180 - 90) * Math.PI / 180, x = f[4 * k + c];
        var r = x > 0 && isFinite(x) ? R * Math.min(1, Math.max(0, (Math.log10(x) - lo) / DECADES)) : 0;
        var px = cx + r * Math.sin(t), py = cy - r * Math.cos(t);
        if (k) ctx.lineTo(px, py); else ctx.moveTo(px, py);
      }
      ctx.stroke();
    }
  }

  var measured = el('brdfcl-measured');
  function drawMeasured(theta, phi) {
    var m = cfg.measured;
    if (!m) return;
    var best = 0;
    m.angles.forEach(function (a, k) { if (Math.abs(a - theta) < Math.abs(m.angles[best] - theta)) best = k; });
    var n = m.angles.length;
    measured.style.backgroundPosition = (n > 1 ? 100 * best / (n - 1) : 0) + '% 0';
    measured.style.transform = 'rotate(' + (-phi) + 'deg)';
    el('brdfcl-measured-text').textContent = 'measured (table): light ' + m.angles[best] + '\u00b0 from the view ' +
      '(the nearest of ' + n + ' drawn, every ' + m.step + '\u00b0), turned to azimuth ' + phi + '\u00b0; ' +
      'fixed exposure, white = ' + m.white.toPrecision(3) + ' /sr';
  }

  var pending = false;
  function later() {
    if (!pending) {
      pending = true;
      requestAnimationFrame(draw);
    }
  }
  function draw() {
    pending = false;
    var theta = +controls.theta.value, phi = +controls.phi.value, ti = +controls.ti.value;
    var stops = +controls.stops.value;
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    gl.viewport(0, 0, canvas.width, canvas.height);
    uniforms(show, {u_size: [canvas.width, canvas.height], u_light: direction(theta, phi),
                    u_scale: Math.pow(2, stops) / white});
    gl.drawArrays(gl.TRIANGLES, 0, 3);
    drawSlice(ti);
    drawMeasured(theta, phi);
    el('brdfcl-theta-v').textContent = theta + '\u00b0';
    el('brdfcl-phi-v').textContent = phi + '\u00b0';
    el('brdfcl-ti-v').textContent = ti + '\u00b0';
    el('brdfcl-stops-v').textContent = (stops > 0 ? '+' : '') + stops.toFixed(1);
    el('brdfcl-fit-text').textContent = 'fit: light (' + direction(theta, phi).map(function (x) {
      return x.toFixed(2);
    }).join(', ') + '), ' + theta + '\u00b0 from the view; white = ' + (white / Math.pow(2, stops)).toPrecision(3) +
      ' /sr (exposure 0: ' + whiteText + ')';
    el('brdfcl-slice-text').textContent = 'fit in the plane of incidence, \u03b8i = ' + ti +
      '\u00b0: BRDF (1/sr, log radius, ' + DECADES + ' decades) against \u03b8o; R, G, B';
    params.forEach(function (q) { q.out.textContent = q.value.toPrecision(4); });
    root.setAttribute('data-ready', '1');
  }
  Object.keys(controls).forEach(function (k) { controls[k].addEventListener('input', later); });
  window.brdfclView = {sphere: function (size, theta, phi) {
    var v = sphere(size, theta, phi);
    draw();
    return v;
  }, slice: slice, white: white};
  draw();
})();
