// The robot screen's building blocks, shared by its delivery screens (robot.js) and those of
// its other modes (guest/robot-modes.js): the big buttons a guest presses, the small ones set
// apart for staff, which tray to take and the dishes on it.

import { el } from "../ui.js";
import { t } from "../i18n.js";
import { listWords } from "./trays.js";

/** A button for a finger from a step away; `onclick(button)`. */
export function bigButton(label, onclick, cls = "primary") {
  return el("button", { class: `big ${cls}`, onclick: (e) => onclick(e.currentTarget), text: label });
}

export function smallButton(label, onclick) {
  return el("button", { class: "secondary small", onclick: (e) => onclick(e.currentTarget), text: label });
}

/** The small controls only staff should press, set apart from the guest's big buttons. */
export function staffControls(...buttons) {
  const shown = buttons.filter(Boolean);
  if (!shown.length) return null;
  return el(
    "div",
    { class: "staff-controls", role: "group", "aria-label": t("guest.robot.forStaff") },
    el("span", { class: "staff-label", "aria-hidden": "true" }, t("guest.robot.forStaff")),
    ...shown,
  );
}

/** "Please take tray 2", "Please take trays 1 and 3"; null when no tray is known. */
export function takeTray(trays) {
  if (!trays.length) return null;
  const words =
    trays.length === 1 ? t("guest.takeTray", { tray: trays[0] }) : t("guest.takeTrays", { trays: listWords(trays) });
  return el("p", { class: "take-tray" }, words);
}

/** A list's items: each dish's label, "…" while it is not loaded, "…" alone for none yet. */
export function dishItems(labels) {
  return labels.length
    ? labels.map((label) => el("li", {}, label ?? t("robot.cartLoading")))
    : [el("li", { class: "muted" }, t("robot.cartLoading"))];
}

/** The dishes of a stop for its guests: "Your dishes", each named with its tray when several. */
export function yourDishes(m) {
  return el("ul", { class: "cart-items", "aria-label": t("robot.yourDishes") }, dishItems(m.cart));
}
