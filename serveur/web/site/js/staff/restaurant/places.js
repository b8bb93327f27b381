// The Restaurant tab's tables and places: add one where a robot stands (`create waypoint` with
// `robot`: a dish return, a charger's dock...), rename one (`site rename_waypoint`), move it or
// change its kind (`create waypoint` with `replace`), or remove it after seeing what depends on
// it (`site dependents`, then `site remove_waypoint`). Its own module so that the panel (restaurant.js)
// only lays the sections out.

import { act, byName, describeError, el, toast } from "../../ui.js";
import { t } from "../../i18n.js";
import { field, formDialog } from "../forms.js";
import { listSection, rowButton } from "./form.js";
import { kindName, PLACE_KINDS } from "../kinds.js";

function kindSelect(id, value) {
  const select = el("select", { id }, ...PLACE_KINDS.map((k) => el("option", { value: k, text: kindName(k) })));
  select.value = value;
  return select;
}

function fixed(v, digits = 2) {
  return v === null || v === undefined || !Number.isFinite(Number(v)) ? "?" : Number(v).toFixed(digits);
}

function degrees(rad) {
  return Math.round((Number(rad) * 180) / Math.PI);
}

/** Degrees as the wire's yaw: radians in (-pi, pi]. */
function radians(deg) {
  let r = (Number(deg) * Math.PI) / 180;
  while (r > Math.PI) r -= 2 * Math.PI;
  while (r <= -Math.PI) r += 2 * Math.PI;
  return Number(r.toFixed(4));
}

export class PlacesSection {
  constructor(conn, live) {
    this.conn = conn;
    this.live = live;
    ({ rows: this.rows, section: this.section } = listSection({
      titleId: "rest-places-title",
      title: "owner.places.title",
      note: "owner.places.note",
      none: "owner.places.none",
      signature: (w) => [w.kind, w.x, w.y, w.yaw],
      build: (w) => this._row(w),
    }, el("div", { class: "form-buttons" }, el("button", { type: "button", class: "secondary", "data-needs-online": true, "data-i18n": "owner.places.add", onclick: () => this._add() }))));
  }

  render() {
    this.rows.update(
      [...this.live.waypoints.values()].sort((a, b) => PLACE_KINDS.indexOf(a.kind) - PLACE_KINDS.indexOf(b.kind) || byName(a.name, b.name)),
    );
  }

  _row(w) {
    return el(
      "li",
      { "data-waypoint": w.name, class: "rest-place" },
      el("span", { class: "rest-name", text: w.name }),
      el("span", { class: "rest-kind", text: kindName(w.kind) }),
      el("span", { class: "muted rest-pos", text: t("owner.places.position", { x: fixed(w.x), y: fixed(w.y), yaw: degrees(w.yaw) }) }),
      el(
        "div",
        { class: "row-actions" },
        rowButton(t("owner.places.rename"), t("owner.places.renameFor", { name: w.name }), () => this._rename(w.name)),
        rowButton(t("owner.places.move"), t("owner.places.moveFor", { name: w.name }), () => this._move(w.name)),
        rowButton(t("owner.remove"), t("owner.places.removeFor", { name: w.name }), (e) => this._remove(w.name, e.currentTarget), { danger: true }),
      ),
    );
  }

  async _rename(name) {
    const input = el("input", { id: "rw-name", type: "text", maxlength: 64, required: true, autocomplete: "off", value: name });
    await formDialog({
      title: t("owner.places.renameTitle", { name }),
      yes: t("owner.places.rename"),
      fields: [field("rw-name", "owner.places.newName", input), el("p", { class: "muted rest-hint", text: t("owner.places.renameNote") })],
      submit: async () => {
        const next = input.value.trim();
        if (!next || next === name) return true;
        const reply = await this.conn.request({ clientmsg: "site", action: "rename_waypoint", waypoint: name, name: next });
        toast(t("owner.places.renamed", { old: name, name: reply.waypoint.name }));
        return true;
      },
    });
  }

  async _move(name) {
    const w = this.live.waypoints.get(name);
    if (!w) return;
    const num = (id, value, step) => el("input", { id, type: "number", step, required: true, inputmode: "decimal", value });
    const x = num("mw-x", fixed(w.x), "0.01");
    const y = num("mw-y", fixed(w.y), "0.01");
    const yaw = el("input", { id: "mw-yaw", type: "number", step: 1, min: -180, max: 360, required: true, inputmode: "numeric", value: degrees(w.yaw) });
    const kind = kindSelect("mw-kind", w.kind);
    await formDialog({
      title: t("owner.places.moveTitle", { name }),
      yes: t("owner.places.move"),
      fields: [
        field("mw-x", "owner.places.x", x),
        field("mw-y", "owner.places.y", y),
        field("mw-yaw", "owner.places.yaw", yaw),
        field("mw-kind", "owner.places.kind", kind),
        el("p", { class: "muted rest-hint", text: t("owner.places.moveNote") }),
      ],
      submit: async () => {
        const msg = {
          clientmsg: "create",
          type: "waypoint",
          name,
          x: Number(x.value),
          y: Number(y.value),
          yaw: radians(yaw.value),
          kind: kind.value,
          replace: true,
        };
        await this.conn.request(msg);
        toast(t("owner.places.moved", { name, x: fixed(msg.x), y: fixed(msg.y) }));
        return true;
      },
    });
  }

  /** A new place where a robot stands now (the owner drove it there, or it is parked there). */
  async _add() {
    const name = el("input", { id: "ap-name", type: "text", maxlength: 64, required: true, autocomplete: "off" });
    const kind = kindSelect("ap-kind", "dish_return");
    const robots = [...this.live.robots.values()].sort((a, b) => byName(a.name, b.name));
    const robot = el("select", { id: "ap-robot", required: true }, ...robots.map((r) => el("option", { value: r.name, text: r.name })));
    await formDialog({
      title: t("owner.places.addTitle"),
      yes: t("owner.places.add"),
      fields: [
        field("ap-name", "owner.places.newName", name),
        field("ap-kind", "owner.places.kind", kind),
        field("ap-robot", "owner.places.where", robot),
        el("p", { class: "muted rest-hint", text: t("owner.places.addNote") }),
      ],
      submit: async () => {
        const msg = { clientmsg: "create", type: "waypoint", name: name.value.trim(), robot: robot.value, kind: kind.value };
        const reply = await this.conn.request(msg);
        toast(t("owner.places.added", { name: reply.waypoint.name, kind: kindName(reply.waypoint.kind) }));
        return true;
      },
    });
  }

  /** What depends on the place, then Remove (only when nothing holds it). */
  async _remove(name, button) {
    const reply = await act(button, () => this.conn.request({ clientmsg: "site", action: "dependents", waypoint: name }));
    if (!reply) return;
    const d = reply.dependents;
    const lines = [];
    if (d.homes.length) lines.push(t("owner.deps.homes", { robots: d.homes.join(", "), count: d.homes.length }));
    if (d.orders.length) lines.push(t("owner.deps.orders", { count: d.orders.length }));
    if (d.trips.length) lines.push(t("owner.deps.trips", { count: d.trips.length }));
    if (d.tokens.length) lines.push(t("owner.deps.tokens", { count: d.tokens.length }));
    if (d.blocked) lines.push(t("owner.deps.blocked"));
    const held = d.homes.length || d.orders.length || d.trips.length;
    const titleId = `dlg-${Math.random().toString(36).slice(2)}`;
    const list = lines.length
      ? el("ul", { class: "rest-deps", "data-testid": "dependents" }, ...lines.map((line) => el("li", { text: line })))
      : el("p", { "data-testid": "dependents", text: t("owner.deps.none") });
    const why = held ? el("p", { class: "rest-error", text: t("owner.deps.refused", { name }) }) : null;
    const failed = el("p", { class: "rest-error", role: "alert" });
    const closeBtn = el("button", { type: "button", class: "secondary", text: t(held ? "owner.close" : "owner.cancel") });
    const removeBtn = held
      ? null
      : el("button", { type: "button", class: "danger", "data-needs-online": true, text: t("owner.places.removeYes", { name }) });
    const dialog = el(
      "dialog",
      { class: "confirm rest-dialog", "aria-labelledby": titleId },
      el("h2", { id: titleId, text: t("owner.places.removeQuestion", { name }) }),
      el("p", { text: t("owner.deps.intro") }),
      list,
      why,
      failed,
      el("div", { class: "dialog-buttons" }, closeBtn, removeBtn),
    );
    const finish = () => {
      dialog.close();
      dialog.remove();
    };
    closeBtn.addEventListener("click", finish);
    dialog.addEventListener("cancel", (e) => {
      e.preventDefault();
      finish();
    });
    if (removeBtn) {
      removeBtn.addEventListener("click", async () => {
        removeBtn.disabled = true;
        try {
          await this.conn.request({ clientmsg: "site", action: "remove_waypoint", waypoint: name });
          finish();
          toast(t("owner.places.removed", { name }));
        } catch (err) {
          // Something came to depend on it meanwhile: the server says what.
          failed.textContent = describeError(err);
          removeBtn.disabled = false;
        }
      });
    }
    document.body.append(dialog);
    dialog.showModal();
    closeBtn.focus();
  }
}
