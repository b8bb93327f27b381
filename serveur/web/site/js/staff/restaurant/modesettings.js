// The settings of what robots do besides delivering, in the Restaurant tab's settings form
// (settings.js sends them with the others in `site set_settings`): when a call nobody answered
// is escalated, how long a robot waits for used plates and how long plates may hold back a dish
// at the pass, the battery levels to go and charge and to come back at (as percentages: the
// wire's fractions), and a cruise's pause at each place and after a touch.

import { el } from "../../ui.js";
import { t } from "../../i18n.js";
import { field } from "../forms.js";

// [setting, input id, label key, min, max, as percent]: the server's ranges (wire/owner.py).
const FIELDS = [
  ["call_escalate", "set-call-escalate", "owner.settings.callEscalate", 15, 3600, false],
  ["bussing_wait", "set-bussing-wait", "owner.settings.bussingWait", 10, 1800, false],
  ["bussing_max_delay", "set-bussing-delay", "owner.settings.bussingDelay", 0, 1800, false],
  ["charge_below", "set-charge-below", "owner.settings.chargeBelow", 5, 80, true],
  ["charge_until", "set-charge-until", "owner.settings.chargeUntil", 20, 100, true],
  ["cruise_pause", "set-cruise-pause", "owner.settings.cruisePause", 0, 600, false],
  ["cruise_resume", "set-cruise-resume", "owner.settings.cruiseResume", 5, 600, false],
];

// Which fields go in which group, with the group's title and what it means.
const GROUPS = [
  ["owner.settings.calls", "owner.settings.callsNote", ["call_escalate"]],
  ["owner.settings.plates", "owner.settings.platesNote", ["bussing_wait", "bussing_max_delay"]],
  ["owner.settings.charging", "owner.settings.chargingNote", ["charge_below", "charge_until"]],
  ["owner.settings.cruising", "owner.settings.cruisingNote", ["cruise_pause", "cruise_resume"]],
];

export class ModeFields {
  constructor() {
    this.inputs = new Map(); // setting -> {input, percent}
    for (const [key, id, , min, max, percent] of FIELDS) {
      const input = el("input", { id, type: "number", min, max, step: 1, inputmode: "numeric", required: true });
      this.inputs.set(key, { input, percent });
    }
    this.nodes = GROUPS.map(([title, note, keys]) =>
      el(
        "fieldset",
        { class: "rest-langs rest-modes" },
        el("legend", { "data-i18n": title }),
        el("p", { class: "muted rest-hint", "data-i18n": note }),
        ...keys.map((key) => {
          const [, id, label] = FIELDS.find((f) => f[0] === key);
          return field(id, label, this.inputs.get(key).input);
        }),
      ),
    );
    const { input: until } = this.inputs.get("charge_until");
    this.inputs.get("charge_below").input.addEventListener("input", () => this.check());
    until.addEventListener("input", () => this.check());
  }

  /** The settings read or saved, in the fields. */
  fill(settings) {
    for (const [key, { input, percent }] of this.inputs) {
      const v = settings[key];
      input.value = typeof v === "number" ? String(Math.round(percent ? v * 100 : v)) : "";
    }
    this.check();
  }

  /** Back to work only above the level it goes to charge at. */
  check() {
    const below = Number(this.inputs.get("charge_below").input.value);
    const { input: until } = this.inputs.get("charge_until");
    const wrong = until.value !== "" && Number(until.value) <= below;
    until.setCustomValidity(wrong ? t("owner.settings.chargeOrder") : "");
  }

  /** The fields as `set_settings` takes them. */
  values() {
    const out = {};
    for (const [key, { input, percent }] of this.inputs) {
      const n = Number(input.value);
      out[key] = percent ? Math.round(n) / 100 : n;
    }
    return out;
  }
}
