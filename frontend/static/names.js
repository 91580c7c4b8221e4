// Lookups over the server's vocabulary (/static/vocabulary.js, generated from the Python
// definitions): the lists and labels every page shows. No page spells a column, model,
// action or controller name of its own; what is missing here belongs in the vocabulary.
import VOCABULARY from "/static/vocabulary.js";

export { VOCABULARY };
const names = (list) => list.map((x) => x.name);
const byName = (list) => new Map(list.map((x) => [x.name, x]));

export const MODEL_NAMES = names(VOCABULARY.models);
export const CATEGORY_NAMES = names(VOCABULARY.categories);
export const SEGMENT_LABELS = names(VOCABULARY.segment_labels);
export const CONTROLLER_NAMES = names(VOCABULARY.controllers);
// The controllers the paper's tables compare: every one but the idle one and the
// baselines (springs free, no exoskeleton), which never lock.
export const STUDY_CONTROLLERS = VOCABULARY.controllers.filter((c) => !c.idle && !c.baseline).map((c) => c.name);
// The baseline conditions, in plan order: plan entries the muscle-activity tables measure
// each controller's reduction against.
export const BASELINES = VOCABULARY.controllers.filter((c) => c.baseline).map((c) => c.name);
// The resting controller the worker starts with and returns to (it never locks).
export const IDLE_CONTROLLER = VOCABULARY.controllers.find((c) => c.idle)?.name ?? null;
export const SCRIPTS = VOCABULARY.scripts;

const controllers = byName(VOCABULARY.controllers);
const models = byName([...VOCABULARY.categories, ...VOCABULARY.segment_labels]);
const actionsByValue = new Map(VOCABULARY.actions.map((a) => [a.value, a]));
const actionsByName = byName(VOCABULARY.actions);

// What a controller declares about itself (label, colour, capabilities), or null.
export function controllerInfo(name) {
  return controllers.get(name) ?? null;
}

const variants = byName(VOCABULARY.condition_variants);

// "eumc" -> "E-UMC"; a condition's key reads with its variant, "umc+personal" ->
// "UMC (personal models)"; a name the vocabulary does not know is shown as given.
export function controllerLabel(name) {
  const known = controllers.get(name);
  if (known || name == null) return known?.label ?? name;
  const [base, ...rest] = String(name).split("+");
  if (!rest.length) return name;
  const variant = rest.join("+");
  return `${controllers.get(base)?.label ?? base} (${variants.get(variant)?.label ?? variant})`;
}

// Controller cells read "UMC", "E-UMC", "umc", "eumc", "springs free", "springs_free",
// and a condition's "UMC (personal models)" or "umc+personal": one key for all of them,
// the controller's name (a cell no controller has is squashed).
const squash = (cell) => String(cell ?? "").toLowerCase().replace(/[^a-z]/g, "");
const keys = new Map(VOCABULARY.controllers.flatMap((c) => [[squash(c.label), c.name], [squash(c.name), c.name]]));
export function controllerKey(cell) {
  const text = String(cell ?? "").replace(/\s*\(.*\)\s*$/, "").split("+")[0];
  return keys.get(squash(text)) ?? squash(text);
}

// "stoop_left" -> "stoop left" (models, categories and segment labels).
export function modelLabel(name) {
  return models.get(name)?.label ?? String(name).replaceAll("_", " ");
}

// Action by its tick value (1..4) or its name ("lock_both").
export function action(valueOrName) {
  return actionsByValue.get(valueOrName) ?? actionsByName.get(valueOrName) ?? null;
}

export function actionLabel(value) {
  return action(value)?.label ?? String(value);
}

// The action a lift of this model should get first ("squat" -> "lock_both").
export function correctAction(model) {
  return VOCABULARY.models.find((m) => m.name === model)?.correct_action ?? null;
}

// The labels of the bits set in a `plausibility` value, lowest bit first.
export function plausibilityReasons(bits) {
  return VOCABULARY.plausibility.filter((p) => bits & p.bit).map((p) => p.label);
}

// A tick column's name, checked against the Python record: a misspelt or removed
// column fails when the page loads, not silently as an empty plot.
const TICK_FIELDS = new Set(VOCABULARY.tick_fields);
export function tickColumn(name) {
  if (!TICK_FIELDS.has(name)) throw new Error(`no tick column ${name}`);
  return name;
}

// `prefix` + each model name: the per-model tick columns ("post_" -> post_squat, ...).
export function modelColumns(prefix, list = MODEL_NAMES) {
  return list.map((m) => `${prefix}${m}`);
}
