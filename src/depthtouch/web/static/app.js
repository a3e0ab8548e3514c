// depthtouch page: live height view with touches and trails, drawing pad, pinch zoom and the
// 4-target calibration flow; with several cameras, each camera's part of the screen and the
// overlaps on the pad, and the calibration flow per camera. Plain JavaScript, no build step; all state lives in `state`
// (exposed as window.depthtouch for debugging and tests).
"use strict";

(() => {
  const $ = (id) => document.getElementById(id);
  const live = $("live"), liveCtx = live.getContext("2d");
  const pad = $("pad"), padCtx = pad.getContext("2d");
  const overlay = $("pad-overlay"), overlayCtx = overlay.getContext("2d");
  const zoomView = $("zoomview"), zoomCtx = zoomView.getContext("2d");

  const TRAIL_POINTS = 90;     // positions kept per touch trail
  const TRAIL_KEEP_S = 1.5;    // a lifted touch's trail stays this long (frame time)
  const STILL_PX = 12;         // calibration: a touch must stay within this (depth px)
  const MISSING_FRAMES = 3;     // frames a touch may be absent (no "up") before it ends
  const PINCH_MIN_PX = 8;      // a pinch starting closer than this (depth px) is ignored
  const PAD_BG = "#fafafa";

  const state = {
    res: null,                 // depth image [W, H]
    padWH: [pad.width, pad.height],
    cal: { loaded: false, screen_wh: [pad.width, pad.height], error_px: null },
    targets: null,             // calibration targets in pad pixels
    heightImage: null,         // latest ImageBitmap of the height map
    touches: new Map(),        // id -> last touch {id, state, x, y, sx?, sy?}
    trails: new Map(),         // id -> {pts: [[x, y]...], endT: null | t}
    lastPad: new Map(),        // id -> last pad point of the stroke
    seen: new Set(),
    pinch: null,               // {key, d0, z0}
    zoom: 1,
    calib: null,               // {i, pairs, cur: {id, pts} | null, cam, targets, screenWH}
    cameras: null,             // the last "cameras" message (several cameras), or null
    frames: 0,                 // frame messages received
    lastFrame: -1,             // index of the latest frame
    t: 0,
  };
  window.depthtouch = state;

  const colour = (id) => `hsl(${(id * 67) % 360}, 85%, 55%)`;

  // --- coordinates --------------------------------------------------------------------------
  function depthToPad(x, y) {
    const [W, H] = state.res || state.padWH;
    const s = Math.min(pad.width / W, pad.height / H);
    return [(pad.width - W * s) / 2 + x * s, (pad.height - H * s) / 2 + y * s];
  }

  function screenToPad(x, y, screenWH) {
    return [(x * pad.width) / screenWH[0], (y * pad.height) / screenWH[1]];
  }

  function toPad(t) {
    if (state.cal.loaded && typeof t.sx === "number" && typeof t.sy === "number") {
      const [cw, ch] = state.cal.screen_wh;
      return [(t.sx * pad.width) / cw, (t.sy * pad.height) / ch];
    }
    return depthToPad(t.x, t.y);
  }

  // --- drawing pad --------------------------------------------------------------------------
  function clearPad() {
    padCtx.fillStyle = PAD_BG;
    padCtx.fillRect(0, 0, pad.width, pad.height);
    state.lastPad.clear();
  }

  function strokeTo(t) {
    const p = toPad(t);
    const last = state.lastPad.get(t.id);
    padCtx.strokeStyle = colour(t.id);
    padCtx.fillStyle = colour(t.id);
    padCtx.lineWidth = 5;
    padCtx.lineCap = "round";
    padCtx.lineJoin = "round";
    if (last) {
      padCtx.beginPath();
      padCtx.moveTo(last[0], last[1]);
      padCtx.lineTo(p[0], p[1]);
      padCtx.stroke();
    } else {
      padCtx.beginPath();
      padCtx.arc(p[0], p[1], 2.5, 0, 2 * Math.PI);
      padCtx.fill();
    }
    state.lastPad.set(t.id, p);
  }

  // --- touches ------------------------------------------------------------------------------
  function trackTouch(t) {
    state.touches.set(t.id, t);
    if (!state.seen.has(t.id)) {
      state.seen.add(t.id);
      $("seen").textContent = String(state.seen.size);
    }
    let trail = state.trails.get(t.id);
    if (!trail) {
      trail = { pts: [], endT: null };
      state.trails.set(t.id, trail);
    }
    trail.pts.push([t.x, t.y]);
    if (trail.pts.length > TRAIL_POINTS) trail.pts.shift();
    if (!state.calib) strokeTo(t);
    calibMove(t);
  }

  function endTouch(id, t) {
    if (t && !state.calib && state.lastPad.has(id)) strokeTo(t);
    if (t) calibMove(t);
    calibEnd(id);
    state.touches.delete(id);
    state.lastPad.delete(id);
    const trail = state.trails.get(id);
    if (trail) trail.endT = state.t;
  }

  function onFrame(m) {
    if (m.t < state.t) resetTouches(); // a looped recording started again
    state.frames += 1;
    state.lastFrame = m.frame;
    state.t = m.t;
    const present = new Set();
    for (const t of m.touches) {
      if (t.state === "up") {
        endTouch(t.id, t);
      } else {
        present.add(t.id);
        trackTouch(t);
      }
    }
    // A touch's "up" may have been skipped (slow connection): one missing for MISSING_FRAMES
    // frames in a row has ended.
    for (const [id, t] of [...state.touches]) {
      if (present.has(id)) t.missing = 0;
      else if ((t.missing = (t.missing || 0) + 1) >= MISSING_FRAMES) endTouch(id, null);
    }
    for (const [id, trail] of state.trails) {
      if (trail.endT !== null && state.t - trail.endT > TRAIL_KEEP_S) state.trails.delete(id);
    }
    updatePinch();
    showStatus(m.status);
    showTouchList();
  }

  function resetTouches() {
    for (const id of [...state.touches.keys()]) endTouch(id, null);
    state.trails.clear();
    state.pinch = null;
    state.t = 0;
  }

  function showStatus(s) {
    const parts = [
      s.fps == null ? "– fps" : `${s.fps.toFixed(1)} fps`,
      s.ms_per_frame == null ? "– ms/frame" : `${s.ms_per_frame.toFixed(1)} ms/frame`,
      `${s.touches} touch${s.touches === 1 ? "" : "es"}`,
      `frame ${state.lastFrame}`,
    ];
    if (s.learning) parts.push("learning the surface…");
    $("status").textContent = parts.join(" · ");
  }

  function showTouchList() {
    const list = $("touch-list");
    list.replaceChildren(
      ...[...state.touches.values()].map((t) => {
        const li = document.createElement("li");
        li.dataset.id = String(t.id);
        li.style.color = colour(t.id);
        li.textContent = `#${t.id}  x ${t.x.toFixed(1)}  y ${t.y.toFixed(1)}`;
        return li;
      })
    );
  }

  // --- pinch zoom ---------------------------------------------------------------------------
  function setZoom(z) {
    state.zoom = z;
    const el = $("zoom");
    el.dataset.zoom = z.toFixed(3);
    el.textContent = `zoom ${z.toFixed(2)}×`;
  }

  function updatePinch() {
    const ts = [...state.touches.values()];
    if (ts.length !== 2) {
      state.pinch = null;
      return;
    }
    const d = Math.hypot(ts[0].x - ts[1].x, ts[0].y - ts[1].y);
    const key = ts.map((t) => t.id).sort((a, b) => a - b).join(",");
    if (!state.pinch || state.pinch.key !== key) {
      state.pinch = { key, d0: d, z0: state.zoom };
    } else if (state.pinch.d0 >= PINCH_MIN_PX) {
      setZoom(Math.min(10, Math.max(0.2, (state.pinch.z0 * d) / state.pinch.d0)));
    }
  }

  const picture = (() => {
    const c = document.createElement("canvas");
    c.width = zoomView.width;
    c.height = zoomView.height;
    const g = c.getContext("2d");
    g.fillStyle = "#10243a";
    g.fillRect(0, 0, c.width, c.height);
    g.strokeStyle = "#2f5d8a";
    for (let x = 0; x <= c.width; x += 24) { g.beginPath(); g.moveTo(x, 0); g.lineTo(x, c.height); g.stroke(); }
    for (let y = 0; y <= c.height; y += 24) { g.beginPath(); g.moveTo(0, y); g.lineTo(c.width, y); g.stroke(); }
    for (let i = 0; i < 7; i++) {
      g.fillStyle = colour(i + 1);
      g.beginPath();
      g.arc(c.width / 2 + Math.cos(i) * 120, c.height / 2 + Math.sin(i * 1.7) * 90, 14 + 4 * i, 0, 2 * Math.PI);
      g.fill();
    }
    g.fillStyle = "#fff";
    g.font = "bold 36px sans-serif";
    g.textAlign = "center";
    g.fillText("depthtouch", c.width / 2, c.height / 2 + 12);
    return c;
  })();

  function drawZoom() {
    const z = state.zoom, cx = zoomView.width / 2, cy = zoomView.height / 2;
    zoomCtx.setTransform(1, 0, 0, 1, 0, 0);
    zoomCtx.fillStyle = "#000";
    zoomCtx.fillRect(0, 0, zoomView.width, zoomView.height);
    zoomCtx.setTransform(z, 0, 0, z, cx - cx * z, cy - cy * z);
    zoomCtx.drawImage(picture, 0, 0);
    zoomCtx.setTransform(1, 0, 0, 1, 0, 0);
  }

  // --- calibration flow ---------------------------------------------------------------------
  function startCalibration() {
    const cams = state.cameras;
    if (!state.targets && !cams) {
      $("cal-status").textContent = "calibration is not available on this server";
      return;
    }
    delete $("cal-status").dataset.done;
    if (cams) {
      // one camera at a time: its targets (screen px) lie in its part of the shared screen
      const cam = Number($("cal-cam").value || 0);
      const info = cams.cameras[cam];
      state.calib = { i: 0, pairs: [], cur: null, cam, targets: info.targets,
                      screenWH: cams.screen_wh };
    } else {
      state.calib = { i: 0, pairs: [], cur: null, cam: null, targets: state.targets,
                      screenWH: state.padWH };
    }
    state.lastPad.clear();
    calibPrompt();
  }

  function calibPrompt() {
    const c = state.calib;
    const who = c.cam === null ? "" : `camera ${c.cam}: `;
    $("cal-status").textContent =
      `${who}touch target ${c.i + 1} of ${c.targets.length}, hold still, then lift`;
  }

  function calibMove(t) {
    const c = state.calib;
    if (!c) return;
    // a fused touch is in the pixels of its best camera (t.cam): use the calibrated camera's
    if (c.cam !== null && t.cam !== undefined && t.cam !== c.cam) return;
    if (!c.cur) c.cur = { id: t.id, pts: [] };
    if (c.cur.id === t.id) c.cur.pts.push([t.x, t.y]);
  }

  function calibEnd(id) {
    const c = state.calib;
    if (!c || !c.cur || c.cur.id !== id) return;
    const pts = c.cur.pts;
    c.cur = null;
    if (pts.length === 0) return;
    const mx = pts.reduce((a, p) => a + p[0], 0) / pts.length;
    const my = pts.reduce((a, p) => a + p[1], 0) / pts.length;
    const spread = Math.max(...pts.map((p) => Math.hypot(p[0] - mx, p[1] - my)));
    if (spread > STILL_PX) {
      $("cal-status").textContent = `target ${c.i + 1}: the touch moved; touch it again and hold still`;
      return;
    }
    c.pairs.push({ depth: [mx, my], screen: c.targets[c.i] });
    c.i += 1;
    if (c.i < c.targets.length) calibPrompt();
    else finishCalibration(c);
  }

  async function finishCalibration(c) {
    state.calib = null;
    $("cal-status").textContent = "fitting…";
    const request = { screen_wh: c.screenWH, pairs: c.pairs };
    if (c.cam !== null) request.cam = c.cam;
    try {
      const r = await fetch("api/calibration", {
        method: "POST",
        headers: { "Content-Type": "application/json" },
        body: JSON.stringify(request),
      });
      const body = await r.json();
      const who = c.cam === null ? "" : `camera ${c.cam} `;
      $("cal-status").textContent = body.ok
        ? `${who}calibrated: reprojection error ${body.error_px.toFixed(2)} px, saved to ${body.path}`
        : `calibration failed: ${body.error}`;
      $("cal-status").dataset.done = body.ok ? "ok" : "error";
    } catch (e) {
      $("cal-status").textContent = `calibration failed: ${e}`;
      $("cal-status").dataset.done = "error";
    }
  }

  // --- rendering ----------------------------------------------------------------------------
  function drawLive() {
    const [W, H] = state.res || [live.width, live.height];
    if (live.width !== W || live.height !== H) {
      live.width = W;
      live.height = H;
    }
    if (state.heightImage) liveCtx.drawImage(state.heightImage, 0, 0, W, H);
    else {
      liveCtx.fillStyle = "#222";
      liveCtx.fillRect(0, 0, W, H);
    }
    const r = Math.max(3, W / 80);
    for (const [id, trail] of state.trails) {
      liveCtx.strokeStyle = colour(id);
      liveCtx.lineWidth = Math.max(1.5, W / 320);
      liveCtx.beginPath();
      trail.pts.forEach(([x, y], k) => (k ? liveCtx.lineTo(x, y) : liveCtx.moveTo(x, y)));
      liveCtx.stroke();
    }
    liveCtx.font = `${Math.round(r * 2.2)}px sans-serif`;
    for (const t of state.touches.values()) {
      liveCtx.fillStyle = colour(t.id);
      liveCtx.strokeStyle = "#fff";
      liveCtx.beginPath();
      liveCtx.arc(t.x, t.y, r, 0, 2 * Math.PI);
      liveCtx.fill();
      liveCtx.stroke();
      liveCtx.fillText(String(t.id), t.x + r * 1.3, t.y - r * 1.3);
    }
  }

  function showCameras(m) {
    state.cameras = m;
    const sel = $("cal-cam");
    const keep = sel.value;
    sel.replaceChildren(...m.cameras.map((c) => {
      const o = document.createElement("option");
      o.value = String(c.cam);
      o.textContent = `camera ${c.cam}: ${c.name}`;
      return o;
    }));
    if (keep !== "" && Number(keep) < m.cameras.length) sel.value = keep;
    sel.hidden = m.cameras.length < 2;
    $("cams").textContent = window.depthtouchCameras.legend(m);
  }

  function drawOverlay() {
    overlayCtx.clearRect(0, 0, overlay.width, overlay.height);
    if (state.cameras) window.depthtouchCameras.draw(overlayCtx, state.cameras, screenToPad);
    if (state.calib && state.calib.targets) {
      const c = state.calib;
      const [x, y] = screenToPad(c.targets[c.i][0], c.targets[c.i][1], c.screenWH);
      overlayCtx.strokeStyle = "#d22";
      overlayCtx.lineWidth = 3;
      overlayCtx.beginPath();
      overlayCtx.arc(x, y, 18, 0, 2 * Math.PI);
      overlayCtx.moveTo(x - 28, y);
      overlayCtx.lineTo(x + 28, y);
      overlayCtx.moveTo(x, y - 28);
      overlayCtx.lineTo(x, y + 28);
      overlayCtx.stroke();
    }
    for (const t of state.touches.values()) {
      const [x, y] = toPad(t);
      overlayCtx.strokeStyle = colour(t.id);
      overlayCtx.lineWidth = 2;
      overlayCtx.beginPath();
      overlayCtx.arc(x, y, 12, 0, 2 * Math.PI);
      overlayCtx.stroke();
    }
  }

  function render() {
    drawLive();
    drawOverlay();
    drawZoom();
    requestAnimationFrame(render);
  }

  // --- connection ---------------------------------------------------------------------------
  function onMessage(m) {
    switch (m.type) {
      case "frame":
        onFrame(m);
        break;
      case "hello":
        state.padWH = m.pad_wh;
        pad.width = overlay.width = m.pad_wh[0];
        pad.height = overlay.height = m.pad_wh[1];
        clearPad();
        state.targets = m.targets;
        state.res = m.resolution_wh;
        $("source").textContent = m.source ? `source: ${m.source}` : "";
        setCalibration(m.calibration);
        break;
      case "meta":
        state.res = m.resolution_wh;
        break;
      case "calibration":
        setCalibration(m);
        break;
      case "cameras":
        showCameras(m);
        break;
      case "reset":
        resetTouches();
        $("info").textContent = m.message || "";
        break;
      case "info":
        $("info").textContent = m.message || "";
        break;
    }
  }

  function setCalibration(c) {
    state.cal = c;
    $("pad-mode").textContent = c.loaded
      ? `calibrated screen coordinates (error ${c.error_px == null ? "?" : c.error_px.toFixed(2)} px)`
      : "depth coordinates, scaled to fit";
  }

  function connect() {
    const url = new URL("ws?height=1", window.location.href);  // the page shows height maps
    url.protocol = url.protocol === "https:" ? "wss:" : "ws:";
    const ws = new WebSocket(url);
    ws.binaryType = "blob";
    ws.onopen = () => {
      $("conn").textContent = "connected";
      $("conn").className = "ok";
    };
    ws.onmessage = (ev) => {
      if (typeof ev.data === "string") onMessage(JSON.parse(ev.data));
      else {
        createImageBitmap(ev.data).then((bmp) => {
          if (state.heightImage) state.heightImage.close();
          state.heightImage = bmp;
        }, () => {});
      }
    };
    ws.onclose = () => {
      $("conn").textContent = "disconnected, retrying…";
      $("conn").className = "bad";
      setTimeout(connect, 1000);
    };
  }

  $("clear").addEventListener("click", clearPad);
  $("calibrate").addEventListener("click", startCalibration);
  $("zoom-reset").addEventListener("click", () => {
    setZoom(1);
    state.pinch = null;
  });
  clearPad();
  connect();
  requestAnimationFrame(render);
})();
