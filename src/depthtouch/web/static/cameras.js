// depthtouch page, several cameras: each camera's part of the shared screen (its footprint) and
// the overlaps, drawn on the pad's overlay from the server's "cameras" message. Loaded before
// app.js; exposes window.depthtouchCameras.
"use strict";

(() => {
  const camColour = (k, a) => `hsla(${(200 + k * 140) % 360}, 70%, 45%, ${a})`;

  function path(ctx, pts, screenWH, toPad) {
    ctx.beginPath();
    pts.forEach(([x, y], k) => {
      const [px, py] = toPad(x, y, screenWH);
      if (k) ctx.lineTo(px, py);
      else ctx.moveTo(px, py);
    });
    ctx.closePath();
  }

  // m: the "cameras" message; toPad(x, y, screenWH) -> pad pixels
  function draw(ctx, m, toPad) {
    ctx.lineWidth = 2;
    for (const c of m.cameras) {
      if (!c.footprint) continue;
      path(ctx, c.footprint, m.screen_wh, toPad);
      ctx.fillStyle = camColour(c.cam, 0.08);
      ctx.fill();
      ctx.strokeStyle = camColour(c.cam, 0.9);
      ctx.stroke();
      const n = c.footprint.length;
      const cx = c.footprint.reduce((a, p) => a + p[0], 0) / n;
      const cy = c.footprint.reduce((a, p) => a + p[1], 0) / n;
      const [lx, ly] = toPad(cx, cy, m.screen_wh);
      ctx.fillStyle = camColour(c.cam, 0.9);
      ctx.font = "14px sans-serif";
      ctx.fillText(`camera ${c.cam}`, lx - 28, ly);
    }
    for (const o of m.overlaps) {
      path(ctx, o.polygon, m.screen_wh, toPad);
      ctx.fillStyle = "rgba(120, 60, 160, 0.18)";
      ctx.fill();
    }
  }

  function legend(m) {
    const parts = m.cameras.filter((c) => c.footprint).length;
    const n = m.overlaps.length;
    return `${m.cameras.length} cameras, ${parts} part${parts === 1 ? "" : "s"} shown, `
      + `${n} overlap${n === 1 ? "" : "s"}`;
  }

  window.depthtouchCameras = { draw, legend, colour: camColour };
})();
