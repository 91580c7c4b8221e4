// The model plot's 95 % confidence ellipse of a 2x2 covariance, against closed forms.
import assert from "node:assert/strict";
import { test } from "node:test";
import { ellipse } from "/static/modelplot.js";

const CHI2 = -2 * Math.log(0.05);  // chi-square quantile, 2 dof: exact closed form

test("axis-aligned covariance: semi-axes sqrt(chi2 * variance), no rotation", () => {
  const e = ellipse([[4, 0], [0, 1]]);
  assert.ok(Math.abs(e.rx - Math.sqrt(CHI2 * 4)) < 1e-9);
  assert.ok(Math.abs(e.ry - Math.sqrt(CHI2)) < 1e-9);
  assert.equal(e.angle, 0);
  assert.equal(ellipse([[1, 0], [0, 4]]).angle, Math.PI / 2);
});

test("correlated covariance: eigenvalues 1 +- rho along the diagonals", () => {
  const rho = 0.6;
  const e = ellipse([[1, rho], [rho, 1]]);
  assert.ok(Math.abs(e.rx - Math.sqrt(CHI2 * (1 + rho))) < 1e-9);
  assert.ok(Math.abs(e.ry - Math.sqrt(CHI2 * (1 - rho))) < 1e-9);
  assert.ok(Math.abs(e.angle - Math.PI / 4) < 1e-9);
});
