// New order's "Special (birthday)" on a line: ticked, the dish is a special delivery with a
// message (at most 120 characters) that the robot shows big at the table while it plays a
// birthday song, and waits for Done (`create order` with `special`, docs/protocol.md).
// A line's `special` is null (an ordinary dish) or the message being typed.

import { el } from "../ui.js";
import { t } from "../i18n.js";

export const SPECIAL_MAX = 120;

/** Whether a kept line's `special` is well formed (storage is the device's). */
export function validSpecial(special) {
  return special === undefined || special === null || (typeof special === "string" && special.length <= SPECIAL_MAX);
}

/** The line's tick and message; `changed()` after each change (the draft is kept). */
export function specialControls(line, changed) {
  const id = `special-${line.key}`;
  const box = el("input", { type: "checkbox", id: `${id}-on`, checked: line.special !== null && line.special !== undefined });
  const message = el("input", {
    type: "text",
    id: `${id}-text`,
    class: "special-text",
    maxlength: SPECIAL_MAX,
    autocomplete: "off",
    value: line.special || "",
    placeholder: t("order.specialPlaceholder"),
    "aria-label": t("order.specialFor", { dish: line.dish, table: line.table }),
  });
  const show = () => {
    message.hidden = !box.checked;
    message.required = box.checked;
  };
  box.addEventListener("change", () => {
    line.special = box.checked ? message.value : null;
    show();
    if (box.checked) message.focus();
    changed();
  });
  message.addEventListener("input", () => {
    line.special = message.value;
    changed();
  });
  show();
  line.specialInput = message; // focused when the message is missing at send
  return el(
    "span",
    { class: "special" },
    el(
      "label",
      { class: "check", for: `${id}-on` },
      box,
      el("span", {}, t("order.special")),
      el("span", { class: "visually-hidden" }, t("order.specialOf", { dish: line.dish, table: line.table })),
    ),
    message,
  );
}
