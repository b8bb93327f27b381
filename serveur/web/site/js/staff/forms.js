// The console's modal forms: a dialog holding labelled fields, whose submit sends a request and
// shows the server's refusal inside the form. Used by the Restaurant tab's sections
// (restaurant/*.js) and by the map's zone tool (maptools.js); it imports nothing of either, so
// neither reaches the other through it.

import { describeError, el } from "../ui.js";
import { t } from "../i18n.js";

/** A modal form: resolves with true when submitted (and `submit` did not return false). */
export function formDialog({ title, fields, yes, danger = false, submit }) {
  return new Promise((resolve) => {
    const titleId = `dlg-${Math.random().toString(36).slice(2)}`;
    const yesBtn = el("button", { type: "submit", class: danger ? "danger" : "primary", "data-needs-online": true, text: yes });
    const noBtn = el("button", { type: "button", class: "secondary", text: t("owner.cancel") });
    const why = el("p", { class: "rest-error", role: "alert" });
    const form = el("form", { class: "rest-form", method: "dialog" }, ...fields, why, el("div", { class: "dialog-buttons" }, noBtn, yesBtn));
    const dialog = el("dialog", { class: "confirm rest-dialog", "aria-labelledby": titleId }, el("h2", { id: titleId }, title), form);
    const finish = (answer) => {
      dialog.close();
      dialog.remove();
      resolve(answer);
    };
    form.addEventListener("submit", async (e) => {
      e.preventDefault();
      if (!form.reportValidity() || yesBtn.disabled) return;
      why.textContent = "";
      yesBtn.disabled = true;
      try {
        if (await submit()) finish(true);
      } catch (err) {
        why.textContent = describeError(err); // the server's refusal, in the form it refuses
      } finally {
        yesBtn.disabled = false;
      }
    });
    noBtn.addEventListener("click", () => finish(false));
    dialog.addEventListener("cancel", (e) => {
      e.preventDefault();
      finish(false);
    });
    document.body.append(dialog);
    dialog.showModal();
    const first = form.querySelector("input, select");
    (first || noBtn).focus();
  });
}

export function field(id, labelKey, control, hint = null) {
  return el("div", { class: "rest-field" }, el("label", { for: id, "data-i18n": labelKey }), control, hint);
}
