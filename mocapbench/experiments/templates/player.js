// mocapbench player: the original and the decoded skeleton of a clip, overlaid, frame by frame.
// Reads the JSON in <script id="player-data">; draws on <canvas id="view"> (whole body on the left, the focus
// joint magnified on the right) and <canvas id="timeline"> (each frame's largest joint error, the worst frame
// marked). No network: everything it shows is in the page. URL fragment: #entry=N&frame=F|worst.
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("player-data").textContent);
  var ORIGINAL = "#a0a0a0", DECODED = "#1f3f7f", MARK = "#000000";
  // Error colour ramp, 0 -> green, half -> orange, the entry's largest error -> red.
  var RAMP = [[26, 150, 65], [253, 174, 97], [215, 25, 28]];
  var view = document.getElementById("view"), timeline = document.getElementById("timeline");
  var ctx = view.getContext("2d"), tctx = timeline.getContext("2d");
  var ui = {};
  ["entry", "play", "back", "forward", "worst", "scrub", "speed", "azimuth", "frame-text", "error-text",
   "legend", "facts", "entry-note"].forEach(function (id) { ui[id] = document.getElementById(id); });
  var state = {entry: 0, frame: 0, playing: false, speed: 1, azimuth: 0, clock: 0, last: null};
  var cache = {};

  function floats(b64) {
    var bin = atob(b64), bytes = new Uint8Array(bin.length);
    for (var i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    return new Float32Array(bytes.buffer);
  }

  function load(index) {
    if (cache[index]) return cache[index];
    var e = data.entries[index], clip = data.tracks[e.original];
    var J = e.names.length, F = clip.frames;
    var original = floats(clip.positions);
    var decoded = e.decoded === null ? null : floats(data.tracks[e.decoded].positions);
    var errors = new Float32Array(F * J), perFrame = new Float32Array(F);
    if (decoded) {
      for (var f = 0; f < F; f++) {
        var top = 0;
        for (var j = 0; j < J; j++) {
          var k = (f * J + j) * 3;
          var dx = decoded[k] - original[k], dy = decoded[k + 1] - original[k + 1], dz = decoded[k + 2] - original[k + 2];
          var err = Math.sqrt(dx * dx + dy * dy + dz * dz);
          errors[f * J + j] = err;
          if (err > top) top = err;
        }
        perFrame[f] = top;
      }
    }
    var up = {x: 0, y: 1, z: 2}[e.up], across = [0, 1, 2].filter(function (a) { return a !== up; });
    var low = Infinity, high = -Infinity;
    for (var i = up; i < original.length; i += 3) { low = Math.min(low, original[i]); high = Math.max(high, original[i]); }
    cache[index] = {e: e, J: J, F: F, original: original, decoded: decoded, errors: errors, perFrame: perFrame,
                    up: up, across: across, low: low, high: high};
    return cache[index];
  }

  function colour(t) {
    t = Math.max(0, Math.min(1, t));
    var s = t < 0.5 ? t * 2 : (t - 0.5) * 2, a = RAMP[t < 0.5 ? 0 : 1], b = RAMP[t < 0.5 ? 1 : 2];
    return "rgb(" + [0, 1, 2].map(function (c) { return Math.round(a[c] + (b[c] - a[c]) * s); }).join(",") + ")";
  }

  // Screen position of joint j at frame f of a track: the view turns about the up axis by the azimuth and
  // centres the original's joint `centre` across the floor, and `height` (cm on the up axis) vertically.
  function projector(c, f, box, centre, height, pxPerCm) {
    var cos = Math.cos(state.azimuth), sin = Math.sin(state.azimuth);
    var a0 = c.across[0], a1 = c.across[1];
    function horizontal(p, k) { return p[k + a0] * cos + p[k + a1] * sin; }
    var ck = (f * c.J + centre) * 3, cx = horizontal(c.original, ck);
    return function (p, j) {
      var k = (f * c.J + j) * 3;
      return [box.x + box.w / 2 + (horizontal(p, k) - cx) * pxPerCm,
              box.y + box.h / 2 - (p[k + c.up] - height) * pxPerCm];
    };
  }

  function drawSkeleton(c, p, project, bone, boneWidth, jointRadius, jointColour) {
    var parents = c.e.parents;
    ctx.strokeStyle = bone; ctx.lineWidth = boneWidth; ctx.lineCap = "round";
    ctx.beginPath();
    for (var j = 1; j < c.J; j++) {
      var a = project(p, parents[j]), b = project(p, j);
      ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]);
    }
    ctx.stroke();
    for (j = 0; j < c.J; j++) {
      if (j === c.e.worst_joint && jointColour !== null) continue;  // drawn last, on top
      var q = project(p, j);
      ctx.fillStyle = jointColour === null ? bone : jointColour(j);
      ctx.beginPath(); ctx.arc(q[0], q[1], jointRadius, 0, 2 * Math.PI); ctx.fill();
    }
  }

  function panel(c, f, box, pxPerCm, centreJoint, label) {
    ctx.save();
    ctx.beginPath(); ctx.rect(box.x, box.y, box.w, box.h); ctx.clip();
    ctx.fillStyle = "#ffffff"; ctx.fillRect(box.x, box.y, box.w, box.h);
    // whole body: the root across the floor, the clip's vertical extent fits; zoom: the focus joint centred
    var project = centreJoint === null ? projector(c, f, box, 0, (c.low + c.high) / 2, pxPerCm)
      : projector(c, f, box, centreJoint, c.original[(f * c.J + centreJoint) * 3 + c.up], pxPerCm);
    var scale = c.e.scale_cm > 0 ? c.e.scale_cm : 1;
    var big = centreJoint !== null;
    drawSkeleton(c, c.original, project, ORIGINAL, big ? 9 : 5, big ? 6 : 3, null);
    var result = null;
    if (c.decoded) {
      drawSkeleton(c, c.decoded, project, DECODED, big ? 3 : 2, big ? 8 : 4,
                   function (j) { return colour(c.errors[f * c.J + j] / scale); });
      var w = c.e.worst_joint, q = project(c.decoded, w);
      ctx.fillStyle = colour(c.errors[f * c.J + w] / scale);
      ctx.beginPath(); ctx.arc(q[0], q[1], big ? 8 : 4, 0, 2 * Math.PI); ctx.fill();
      if (f === c.e.worst_frame) {
        ctx.strokeStyle = MARK; ctx.lineWidth = 1.5;
        ctx.beginPath(); ctx.arc(q[0], q[1], big ? 14 : 9, 0, 2 * Math.PI); ctx.stroke();
      }
      result = q;
    }
    ctx.restore();
    ctx.fillStyle = "#333"; ctx.font = "13px system-ui, sans-serif";
    ctx.fillText(label, box.x + 6, box.y + 16);
    ctx.strokeStyle = "#ccc"; ctx.lineWidth = 1; ctx.strokeRect(box.x + 0.5, box.y + 0.5, box.w - 1, box.h - 1);
    return result;
  }

  function drawTimeline(c) {
    var W = timeline.width, H = timeline.height, top = 0;
    tctx.fillStyle = "#ffffff"; tctx.fillRect(0, 0, W, H);
    for (var f = 0; f < c.F; f++) top = Math.max(top, c.perFrame[f]);
    function x(f) { return c.F > 1 ? 4 + (W - 8) * f / (c.F - 1) : W / 2; }
    if (c.decoded && top > 0) {
      tctx.strokeStyle = DECODED; tctx.lineWidth = 1; tctx.beginPath();
      for (f = 0; f < c.F; f++) { var y = H - 4 - (H - 8) * c.perFrame[f] / top; f ? tctx.lineTo(x(f), y) : tctx.moveTo(x(f), y); }
      tctx.stroke();
    }
    if (c.e.worst_frame !== null) {
      tctx.fillStyle = colour(1); tctx.fillRect(x(c.e.worst_frame) - 1.5, 0, 3, H);
    }
    tctx.fillStyle = MARK; tctx.fillRect(x(state.frame) - 0.5, 0, 1, H);
  }

  function draw() {
    var c = load(state.entry), f = state.frame;
    var W = view.width, H = view.height, split = Math.round(W * 0.62);
    var main = {x: 0, y: 0, w: split - 4, h: H}, zoom = {x: split, y: 0, w: W - split, h: H};
    var extent = Math.max(c.high - c.low, 1);
    var whole = panel(c, f, main, 0.85 * H / extent, null, "whole body (grey: original, blue: decoded)");
    var focus = c.e.worst_joint === null ? 0 : c.e.worst_joint;
    var zoomCm = Math.max(20 * (c.e.scale_cm || 1), 15);
    panel(c, f, zoom, zoom.h / zoomCm, focus, "around " + c.e.names[focus] + " (x" +
          (zoom.h / zoomCm / (0.85 * H / extent)).toFixed(0) + ")");
    drawTimeline(c);
    var frameError = c.decoded ? c.perFrame[f] : 0;
    ui["frame-text"].textContent = "frame " + (c.e.frame_numbers[f]) + " of " + c.e.source_frames +
      " (" + (c.e.frame_numbers[f] / c.e.fps).toFixed(3) + " s)";
    ui["error-text"].textContent = c.decoded ? "largest joint error in this frame " + frameError.toFixed(3) +
      " cm; worst of the clip " + c.e.max_err_cm.toFixed(3) + " cm at frame " +
      c.e.frame_numbers[c.e.worst_frame] + ", " + c.e.names[c.e.worst_joint] : "one motion, no error to show";
    ui.scrub.value = f;
    var rect = view.getBoundingClientRect(), sx = rect.width / view.width, sy = rect.height / view.height;
    ui.facts.textContent = JSON.stringify({
      entry: state.entry, frame: f, worstFrame: c.e.worst_frame, worstJoint: c.e.worst_joint,
      worstPage: whole ? [rect.left + window.scrollX + whole[0] * sx, rect.top + window.scrollY + whole[1] * sy] : null,
      worstColour: colour(1), original: ORIGINAL, decoded: DECODED});
  }

  function setEntry(index) {
    state.entry = Math.max(0, Math.min(data.entries.length - 1, index));
    var c = load(state.entry);
    ui.entry.value = String(state.entry);
    ui.scrub.max = c.F - 1;
    state.frame = Math.min(state.frame, c.F - 1);
    ui["entry-note"].textContent = c.e.note || "";
    var scale = c.e.scale_cm;
    ui.legend.innerHTML = "";
    if (c.decoded) {
      [0, 0.25, 0.5, 0.75, 1].forEach(function (t) {
        var chip = document.createElement("span");
        chip.className = "chip"; chip.style.background = colour(t);
        ui.legend.appendChild(chip);
        ui.legend.appendChild(document.createTextNode(" " + (t * scale).toFixed(2) + " cm  "));
      });
    }
    draw();
  }

  function seek(f) {
    var c = load(state.entry);
    state.frame = Math.max(0, Math.min(c.F - 1, f));
    state.clock = state.frame;
    draw();
  }

  function tick(now) {
    if (!state.playing) { state.last = null; return; }
    var c = load(state.entry);
    if (state.last !== null) {
      state.clock += (now - state.last) / 1000 * c.e.fps_shown * state.speed;
      if (state.clock >= c.F) state.clock = 0;
      state.frame = Math.floor(state.clock);
      draw();
    }
    state.last = now;
    requestAnimationFrame(tick);
  }

  function togglePlay() {
    state.playing = !state.playing;
    ui.play.textContent = state.playing ? "pause" : "play";
    state.clock = state.frame;
    if (state.playing) requestAnimationFrame(tick);
  }

  data.entries.forEach(function (e, i) {
    var option = document.createElement("option");
    option.value = String(i); option.textContent = e.label;
    ui.entry.appendChild(option);
  });
  ui.entry.addEventListener("change", function () { setEntry(parseInt(ui.entry.value, 10)); });
  ui.play.addEventListener("click", togglePlay);
  ui.back.addEventListener("click", function () { seek(state.frame - 1); });
  ui.forward.addEventListener("click", function () { seek(state.frame + 1); });
  ui.worst.addEventListener("click", function () { var w = load(state.entry).e.worst_frame; if (w !== null) seek(w); });
  ui.scrub.addEventListener("input", function () { seek(parseInt(ui.scrub.value, 10)); });
  ui.speed.addEventListener("change", function () { state.speed = parseFloat(ui.speed.value); });
  ui.azimuth.addEventListener("input", function () { state.azimuth = parseFloat(ui.azimuth.value) * Math.PI / 180; draw(); });
  timeline.addEventListener("click", function (event) {
    var rect = timeline.getBoundingClientRect(), c = load(state.entry);
    seek(Math.round((event.clientX - rect.left) / rect.width * (c.F - 1)));
  });
  document.addEventListener("keydown", function (event) {
    if (event.target.tagName === "SELECT" || event.target.tagName === "INPUT" && event.target.type !== "range") return;
    if (event.key === " ") { togglePlay(); event.preventDefault(); }
    else if (event.key === "ArrowLeft") { seek(state.frame - 1); event.preventDefault(); }
    else if (event.key === "ArrowRight") { seek(state.frame + 1); event.preventDefault(); }
  });

  var wanted = {};
  location.hash.replace(/^#/, "").split("&").forEach(function (pair) {
    var kv = pair.split("="); if (kv.length === 2) wanted[kv[0]] = decodeURIComponent(kv[1]);
  });
  setEntry(wanted.entry ? parseInt(wanted.entry, 10) || 0 : 0);
  if (wanted.frame === "worst") ui.worst.click();
  else if (wanted.frame) seek(parseInt(wanted.frame, 10) || 0);
})();
