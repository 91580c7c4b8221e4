// The paper's utility figure: each action's utility minus that of "no lock", one plot
// per motion, over the motion's progress.
import { makePlot } from "/static/plot.js";
import { MODEL_NAMES, modelLabel, VOCABULARY } from "/static/names.js";
import { actionColour } from "/static/palette.js";

// Every action that locks a side (the curves are differences to "no lock"), a2..a4.
const ACTIONS = VOCABULARY.actions.filter((a) => a.lock_left || a.lock_right)
  .map((a) => [a.name, a.label, actionColour(a.name)]);

export function createUtilityPlots(root) {
  root.replaceChildren();
  const plots = MODEL_NAMES.map((key) => {
    const box = document.createElement("div");
    box.className = "utility-plot";
    box.dataset.motion = key;
    const h = document.createElement("h3");
    h.className = "small";
    h.textContent = modelLabel(key);
    const el = document.createElement("div");
    box.append(h, el);
    root.append(box);
    const plot = makePlot(el, {
      axes: [{ label: "progress (%)" }, { label: "ΔU vs no lock", size: 78 }],
      series: [{}, ...ACTIONS.map(([, label, stroke]) => ({ label, stroke, width: 2 }))],
    }, { height: 220, sync: "exostudy-utilities" });
    return { key, el, plot };
  });
  const note = document.createElement("p");
  note.className = "small muted";
  root.after(note);
  return {
    setCurves(curves) {
      const x = curves.progress.map((p) => p * 100);
      for (const p of plots) {
        p.plot.setData([x, ...ACTIONS.map(([a]) => curves.differences[p.key][a])]);
      }
      root.dataset.loaded = "true";
      const other = ACTIONS.map(([a, label]) => `${label} ${Number(curves.other[a]).toPrecision(3)}`).join(", ");
      note.textContent = `other motions (constant over progress): ${other}`;
    },
  };
}
