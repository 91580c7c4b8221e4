// The paper's utility figure: each action's utility minus that of "no lock", one plot
// per motion, over the motion's progress.
import uPlot from "/vendor/uplot/uPlot.esm.js";
import { sizeOf } from "/static/timeplots.js";

const ACTIONS = [["lock_both", "lock both", "#7048e8"], ["lock_left", "lock left", "#1f6feb"],
  ["lock_right", "lock right", "#d9480f"]];
const MOTIONS = [["squat", "squat"], ["stoop_left", "stoop left"], ["stoop_right", "stoop right"]];

export function createUtilityPlots(root) {
  root.replaceChildren();
  const plots = MOTIONS.map(([key, title]) => {
    const box = document.createElement("div");
    box.className = "utility-plot";
    box.dataset.motion = key;
    const h = document.createElement("h3");
    h.className = "small";
    h.textContent = title;
    const el = document.createElement("div");
    box.append(h, el);
    root.append(box);
    const plot = new uPlot({
      ...sizeOf(el, 220),
      scales: { x: { time: false } },
      cursor: { sync: { key: "exostudy-utilities" } },
      axes: [{ label: "progress (%)" }, { label: "ΔU vs no lock", size: 78 }],
      series: [{}, ...ACTIONS.map(([, label, stroke]) => ({ label, stroke, width: 2 }))],
    }, [[], [], [], []], el);
    return { key, el, plot };
  });
  const note = document.createElement("p");
  note.className = "small muted";
  root.after(note);
  window.addEventListener("resize", () => plots.forEach((p) => p.plot.setSize(sizeOf(p.el, 220))));
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
