// The Restaurant tab's pieces, shared by its sections: a section listing things by name, a
// row's action button, and "ask, then remove" — written once here so that every section builds
// them the same way. (The modal form an edit opens and its labelled fields are ../forms.js: the
// map's zone tool uses them too.)

import { act, confirmDialog, el, KeyedList, toast } from "../../ui.js";
import { t } from "../../i18n.js";

/** A list row's action button: its words, the aria-label naming its row, `onclick`; a
 *  "danger" one (remove) or a "secondary" one, disabled while offline. */
export function rowButton(text, label, onclick, { danger = false } = {}) {
  return el("button", { class: danger ? "danger" : "secondary", "data-needs-online": true, "aria-label": label, text, onclick });
}

/** The row's Remove, asked first: `question` and `detail` in the dialog (`yes`: the words of
 *  its yes, "Remove" by default), then `run()` on the button (act: disabled meanwhile, a refusal
 *  shown) and `done` said when it succeeded. Resolves true when it was done. */
export async function confirmRemove(button, { question, detail, run, done, yes = t("owner.remove") }) {
  const sure = await confirmDialog(question, { detail, yes, no: t("owner.cancel") });
  if (!sure) return false;
  const reply = await act(button, run);
  if (reply) toast(done);
  return Boolean(reply);
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
