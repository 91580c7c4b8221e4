// The lookups over the server's vocabulary (the module the Python test generated).
import assert from "node:assert/strict";
import { test } from "node:test";
import {
  action, actionLabel, BASELINES, CATEGORY_NAMES, controllerInfo, controllerKey, controllerLabel,
  CONTROLLER_NAMES, correctAction, IDLE_CONTROLLER, MODEL_NAMES, modelColumns, modelLabel, plausibilityReasons, SEGMENT_LABELS,
  STUDY_CONTROLLERS, tickColumn, VOCABULARY,
} from "/static/names.js";

test("controllers: the paper's three by their labels, then the baselines, 'none' last; only the three compared", () => {
  assert.deepEqual(CONTROLLER_NAMES, ["umc", "eumc", "pec", "springs_free", "no_exoskeleton", "none"]);
  assert.deepEqual(STUDY_CONTROLLERS, ["umc", "eumc", "pec"]);
  assert.deepEqual(BASELINES, ["springs_free", "no_exoskeleton"]);
  assert.equal(controllerLabel("no_exoskeleton"), "no exoskeleton");
  assert.equal(controllerLabel("eumc"), "E-UMC");
  assert.equal(controllerLabel("mystery"), "mystery");
  assert.equal(controllerLabel(null), null);
  assert.equal(controllerKey("E-UMC"), "eumc");
  assert.equal(controllerKey("Springs Free"), "springs_free");
  assert.equal(controllerKey("Mystery-1"), "mystery");
  for (const c of CONTROLLER_NAMES) assert.equal(controllerKey(controllerLabel(c)), c);
  // A condition's key reads with its variant, and filters as its controller.
  assert.equal(controllerLabel("umc+personal"), "UMC (personal models)");
  assert.equal(controllerLabel("eumc+personal+priors"), "E-UMC (personal models, learned priors)");
  assert.equal(controllerLabel("umc+odd"), "UMC (odd)");
  assert.equal(controllerKey("UMC (personal models)"), "umc");
  assert.equal(controllerKey("umc+priors"), "umc");
  assert.equal(controllerKey(controllerLabel("eumc+priors")), "eumc");
});

test("controllers declare their capabilities; pages read them, not names", () => {
  assert.equal(IDLE_CONTROLLER, "none");
  assert.equal(controllerInfo("eumc").needs_calibration, true);
  assert.equal(controllerInfo("umc").needs_calibration, false);
  assert.deepEqual(STUDY_CONTROLLERS.map((c) => controllerInfo(c).estimates_intent), [true, true, false]);
  assert.equal(controllerInfo("pec").colour, "#ff7f0e");
  assert.equal(controllerInfo("eumc").plan_optional, true);
  assert.deepEqual(CONTROLLER_NAMES.map((c) => controllerInfo(c).baseline), [false, false, false, true, true, false]);
  assert.deepEqual(BASELINES.map((c) => controllerInfo(c).exoskeleton_worn), [true, false]);
  assert.equal(controllerInfo("springs_free").in_plan, true);
  assert.equal(controllerInfo("mystery"), null);
});

test("models, categories and segment labels", () => {
  assert.deepEqual(MODEL_NAMES, ["squat", "stoop_left", "stoop_right"]);
  assert.deepEqual(CATEGORY_NAMES, [...MODEL_NAMES, "other"]);
  assert.deepEqual(SEGMENT_LABELS, [...CATEGORY_NAMES, "unlabelled"]);
  assert.equal(modelLabel("stoop_right"), "stoop right");
  assert.equal(modelLabel("a_b_c"), "a b c");
  assert.deepEqual(modelColumns("post_"), ["post_squat", "post_stoop_left", "post_stoop_right"]);
});

test("actions are the paper's a1..a4 with their locks", () => {
  assert.deepEqual(VOCABULARY.actions.map((a) => a.value), [1, 2, 3, 4]);
  assert.equal(actionLabel(3), "lock right");
  assert.equal(actionLabel(9), "9");
  assert.deepEqual([action("lock_left").lock_left, action("lock_left").lock_right], [true, false]);
  assert.equal(correctAction("squat"), "lock_both");
  assert.equal(correctAction("stoop_left"), "lock_left");
  assert.equal(correctAction("other"), null);
});

test("plausibility bits name their reasons, lowest bit first", () => {
  assert.deepEqual(plausibilityReasons(0), []);
  assert.deepEqual(plausibilityReasons(1 | 32 | 128), ["angle jump", "out of range", "acceleration"]);
});

test("tick columns are checked against the record", () => {
  assert.equal(tickColumn("q_left"), "q_left");
  assert.throws(() => tickColumn("q_middle"), /no tick column q_middle/);
});

test("the vocabulary cannot be changed by a page", () => {
  assert.ok(Object.isFrozen(VOCABULARY));
  assert.ok(Object.isFrozen(VOCABULARY.controllers[0]));
});
