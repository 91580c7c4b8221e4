// The console's colours, one place: left and right hips, each motion category and each
// action are drawn alike on every plot, legend and band.

export const LEFT = "#1f6feb";
export const RIGHT = "#d9480f";
export const TRIGGER = "#2b8a3e";
export const MARKER = "#9c36b5";
export const NEUTRAL = "#6b7685";

// Motion categories and segment labels, as "r,g,b" so bands can add transparency.
const CATEGORY_RGB = {
  squat: "43,138,62", stoop_left: "31,111,235", stoop_right: "217,72,15",
  other: "134,142,150", unlabelled: "156,54,181",
};
const ACTION_COLOURS = { lock_both: "#7048e8", lock_left: LEFT, lock_right: RIGHT };

// A category's colour, `rgba(...)` with `alpha`; unknown names take the unlabelled one.
export function categoryColour(name, alpha = 1) {
  return `rgba(${CATEGORY_RGB[name] ?? CATEGORY_RGB.unlabelled},${alpha})`;
}

export function actionColour(name) {
  return ACTION_COLOURS[name] ?? NEUTRAL;
}
