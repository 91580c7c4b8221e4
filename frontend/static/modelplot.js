// A fitted model set in the plane of left versus right hip flexion: each motion's mean
// trajectory and its 95 % confidence ellipses along progress (from cov_rad2).

import { categoryColour } from "/static/palette.js";
import { DEG } from "/static/tickdata.js";

// The 95 % quantile of the chi-square distribution with 2 degrees of freedom, -2 ln 0.05.
const CHI2_2DOF_95 = 5.991464547107979;

// Semi-axes and angle of the 95 % ellipse of a 2x2 covariance (in deg^2).
export function ellipse(cov) {
  const a = cov[0][0], b = cov[0][1], d = cov[1][1];
  const tr = (a + d) / 2;
  const disc = Math.sqrt(Math.max(0, ((a - d) / 2) ** 2 + b * b));
  const l1 = Math.max(0, tr + disc);
  const l2 = Math.max(0, tr - disc);
  const angle = Math.abs(b) < 1e-12 ? (a >= d ? 0 : Math.PI / 2) : Math.atan2(l1 - a, b);
  return { rx: Math.sqrt(CHI2_2DOF_95 * l1), ry: Math.sqrt(CHI2_2DOF_95 * l2), angle };
}

export function drawModelSet(canvas, doc, { every = 5 } = {}) {
  const cssSize = canvas.clientWidth || 520;
  const ratio = devicePixelRatio || 1;
  canvas.width = cssSize * ratio;
  canvas.height = cssSize * ratio;
  const ctx = canvas.getContext("2d");
  ctx.scale(ratio, ratio);
  const size = cssSize;
  const pad = { l: 58, r: 14, t: 14, b: 48 };

  const models = Object.entries(doc.models).map(([name, m]) => ({
    name,
    mean: m.mean_rad.map(([l, r]) => [l * DEG, r * DEG]),
    ellipses: m.cov_rad2.map((c) => ellipse(c.map((row) => row.map((v) => v * DEG * DEG)))),
  }));
  let lo = Infinity, hi = -Infinity;
  for (const m of models) {
    m.mean.forEach(([l, r], i) => {
      const e = m.ellipses[i].rx;
      lo = Math.min(lo, l - e, r - e);
      hi = Math.max(hi, l + e, r + e);
    });
  }
  // Same scale on both axes, so a circle of variance looks like one.
  const span = hi - lo || 1;
  lo -= span * 0.04; hi += span * 0.04;
  const w = size - pad.l - pad.r;
  const hgt = size - pad.t - pad.b;
  const X = (v) => pad.l + ((v - lo) / (hi - lo)) * w;
  const Y = (v) => pad.t + hgt - ((v - lo) / (hi - lo)) * hgt;

  ctx.fillStyle = "#fff";
  ctx.fillRect(0, 0, size, size);
  ctx.strokeStyle = "#e6e9ee";
  ctx.fillStyle = "#6b7685";
  ctx.font = "12px system-ui";
  const step = niceStep((hi - lo) / 6);
  for (let v = Math.ceil(lo / step) * step; v <= hi; v += step) {
    ctx.beginPath(); ctx.moveTo(X(v), pad.t); ctx.lineTo(X(v), pad.t + hgt); ctx.stroke();
    ctx.beginPath(); ctx.moveTo(pad.l, Y(v)); ctx.lineTo(pad.l + w, Y(v)); ctx.stroke();
    ctx.textAlign = "center"; ctx.fillText(v.toFixed(0), X(v), pad.t + hgt + 16);
    ctx.textAlign = "right"; ctx.fillText(v.toFixed(0), pad.l - 6, Y(v) + 4);
  }
  ctx.strokeStyle = "#c9ced6";
  ctx.setLineDash([4, 4]);
  ctx.beginPath(); ctx.moveTo(X(lo), Y(lo)); ctx.lineTo(X(hi), Y(hi)); ctx.stroke();
  ctx.setLineDash([]);
  ctx.fillStyle = "#1c2430";
  ctx.font = "13px system-ui";
  ctx.textAlign = "center";
  ctx.fillText("left hip flexion (deg)", pad.l + w / 2, size - 10);
  ctx.save();
  ctx.translate(16, pad.t + hgt / 2);
  ctx.rotate(-Math.PI / 2);
  ctx.fillText("right hip flexion (deg)", 0, 0);
  ctx.restore();

  const scale = w / (hi - lo);
  for (const m of models) {
    ctx.strokeStyle = categoryColour(m.name);
    ctx.fillStyle = categoryColour(m.name, 0.08);
    ctx.lineWidth = 1;
    m.mean.forEach(([l, r], i) => {
      if (i % every !== 0 && i !== m.mean.length - 1) return;
      const e = m.ellipses[i];
      ctx.beginPath();
      // The y axis points up on paper and down on the canvas: mirror the angle.
      ctx.ellipse(X(l), Y(r), e.rx * scale, e.ry * scale, -e.angle, 0, 2 * Math.PI);
      ctx.fill();
      ctx.globalAlpha = 0.55;
      ctx.stroke();
      ctx.globalAlpha = 1;
    });
    ctx.lineWidth = 3;
    ctx.beginPath();
    m.mean.forEach(([l, r], i) => (i ? ctx.lineTo(X(l), Y(r)) : ctx.moveTo(X(l), Y(r))));
    ctx.stroke();
  }
  canvas.dataset.models = String(models.length);
  return models.map((m) => m.name);
}

function niceStep(raw) {
  const p = 10 ** Math.floor(Math.log10(raw));
  for (const m of [1, 2, 5, 10]) if (m * p >= raw) return m * p;
  return 10 * p;
}

// What the plot shows before a model set is fitted.
export function drawEmpty(canvas, text) {
  const size = canvas.clientWidth || 520;
  canvas.width = size * (devicePixelRatio || 1);
  canvas.height = canvas.width;
  const ctx = canvas.getContext("2d");
  ctx.scale(devicePixelRatio || 1, devicePixelRatio || 1);
  ctx.fillStyle = "#f6f7f9";
  ctx.fillRect(0, 0, size, size);
  ctx.fillStyle = "#6b7685";
  ctx.font = "15px system-ui";
  ctx.textAlign = "center";
  ctx.fillText(text, size / 2, size / 2);
  delete canvas.dataset.models;
}
