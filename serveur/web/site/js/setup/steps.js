// The setup page's steps (setup.html): which one shows, and the one line that says what went
// wrong. Shared by the page's modules (setup.js and the steps in this folder), so none of them
// imports another.

import { t } from "../i18n.js";

export const STEPS = ["owner", "restaurant", "robots", "places", "trip"];

const problem = document.getElementById("setup-problem");
const listeners = [];

/** Show the page's problem line (a catalog key and its placeholders), or hide it (null). */
export function say(key, params) {
  problem.hidden = !key;
  problem.textContent = key ? t(key, params) : "";
}

/** Call `f(step)` each time a step is shown. */
export function onShow(f) {
  listeners.push(f);
}

/** Show step `name` (its title says where the owner is; the steps before it are ticked). */
export function show(step) {
  const at = STEPS.indexOf(step);
  for (const [i, name] of STEPS.entries()) {
    document.getElementById(`step-${name}`).hidden = name !== step;
    const item = document.querySelector(`.steps [data-step="${name}"]`);
    if (i === at) item.setAttribute("aria-current", "step");
    else item.removeAttribute("aria-current");
    item.classList.toggle("done", i < at);
  }
  document.querySelector(".setup-main").dataset.step = step;
  // The keyboard's place: the step's title where it has one to land on (a map step), else its
  // first field or link.
  const root = document.getElementById(`step-${step}`);
  const first = root.querySelector("h2[tabindex]") || root.querySelector("input, a");
  if (first) first.focus();
  for (const f of listeners) f(step);
}

/** The step shown now. */
export function current() {
  return document.querySelector(".setup-main").dataset.step || null;
}
