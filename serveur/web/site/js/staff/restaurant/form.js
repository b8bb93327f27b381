// The Restaurant tab's pieces, shared by its sections (the form ones by maptools.js too, through
// restaurant.js): a section listing things by name, the modal form an edit opens, a labelled
// field, a row's action button, and "ask, then remove" — written once here so that every section builds them the same way.

import { act, confirmDialog, describeError, el, KeyedList, toast } from "../../ui.js";
import { t } from "../../i18n.js";

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

/** A list row's action button: its words, the aria-label naming its row, `onclick`; a
 *  "danger" one (remove) or a "secondary" one, disabled while offline. */
export function rowButton(text, label, onclick, { danger = false } = {}) {
  return el("button", { class: danger ? "danger" : "secondary", "data-needs-online": true, "aria-label": label, text, onclick });
}

/** The row's Remove, asked first: `question` and `detail` in the dialog, then `run()` on the
 *  button (act: disabled meanwhile, a refusal shown) and `done` said when it succeeded. */
export async function confirmRemove(button, { question, detail, run, done }) {
  const yes = await confirmDialog(question, { detail, yes: t("owner.remove"), no: t("owner.cancel") });
  if (!yes) return;
  const reply = await act(button, run);
  if (reply) toast(done);
}

/** A section listing one kind of thing by name: its card (the title, the note, the list, then
 *  `extra`) and its rows, kept by name. The catalog keys are given whole (the i18n tests read
 *  them in the source). */
export function listSection({ titleId, title, note, none, signature, build }, ...extra) {
  const list = el("ul", { class: "rest-list", "data-i18n-aria-label": title });
  const rows = new KeyedList(list, { key: (x) => x.name, signature, build, empty: () => el("li", { class: "muted", text: t(none) }) });
  const section = el(
    "section",
    { class: "card", "aria-labelledby": titleId },
    el("h2", { id: titleId, "data-i18n": title }),
    el("p", { class: "muted", "data-i18n": note }),
    list,
    ...extra,
  );
  return { list, rows, section };
}
