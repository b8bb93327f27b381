// The Restaurant tab's zones (issue 21, docs/zones.md): each zone with its capacity, who holds
// it and who waits; draw it again on the map (maptools.js, `create zone` with `replace`), remove
// it (`site remove_zone`), release a lease stuck on a robot (`release`), and import a file of
// zones ({"zones": [{name, points, capacity, wait_at}]}: each sent as `create zone` with `replace`, those
// refused listed with the reason). Its own module so that the panel (restaurant.js) only lays
// the sections out.

import { byName, describeError, el, toast } from "../../ui.js";
import { t } from "../../i18n.js";
import { leaseWords, releaseButtons } from "../leases.js";
import { confirmRemove, listSection, rowButton } from "./form.js";

export class ZonesSection {
  constructor(conn, live) {
    this.conn = conn;
    this.live = live;
    this.file = el("input", { id: "zone-file", type: "file", accept: ".json,application/json", "data-needs-online": true });
    this.file.addEventListener("change", () => this._import());
    this.importReport = el("div", { class: "zone-import-report", role: "status", "data-testid": "zone-import" });
    ({ rows: this.rows, section: this.section } = listSection(
      {
        titleId: "rest-zones-title",
        title: "owner.zones.title",
        note: "owner.zones.note",
        none: "owner.zones.none",
        signature: (z) => [z.capacity, z.points, this.live.leases.get(z.name) || null],
        build: (z) => this._row(z),
      },
      el(
        "div",
        { class: "rest-field zone-import" },
        el("label", { for: "zone-file", "data-i18n": "owner.zones.import" }),
        this.file,
        el("p", { class: "muted rest-hint", "data-i18n": "owner.zones.importNote" }),
      ),
      this.importReport,
    ));
  }

  render() {
    this.rows.update([...this.live.zones.values()].sort((a, b) => byName(a.name, b.name)));
  }

  _row(z) {
    const lease = this.live.leases.get(z.name);
    return el(
      "li",
      { "data-zone": z.name, class: "rest-place rest-zone" },
      el("span", { class: "rest-name", text: z.name }),
      el("span", { class: "rest-kind", text: t("owner.zones.capacity", { count: z.capacity }) }),
      el("span", { class: "muted rest-pos", text: t("owner.zones.corners", { count: z.points.length }) }),
      el("span", { class: "rest-lease", "data-testid": "zone-lease", text: leaseWords(lease) }),
      el(
        "div",
        { class: "row-actions" },
        ...releaseButtons(this.conn, z.name, lease),
        rowButton(t("owner.zones.redraw"), t("owner.zones.redrawFor", { zone: z.name }), () =>
          document.dispatchEvent(new CustomEvent("serveur:redraw-zone", { detail: { zone: z.name } })),
        ),
        rowButton(t("owner.remove"), t("owner.zones.removeFor", { zone: z.name }), (e) => this._remove(z.name, e.currentTarget), { danger: true }),
      ),
    );
  }

  _remove(zone, button) {
    return confirmRemove(button, {
      question: t("owner.zones.removeQuestion", { zone }),
      detail: t("owner.zones.removeDetail"),
      run: () => this.conn.request({ clientmsg: "site", action: "remove_zone", zone }),
      done: t("owner.zones.removed", { zone }),
    });
  }

  /** The file chosen: each of its zones stored (replacing one of the same name); what failed said. */
  async _import() {
    const file = this.file.files && this.file.files[0];
    if (!file) return;
    this.importReport.replaceChildren();
    let zones;
    try {
      const doc = JSON.parse(await file.text());
      zones = Array.isArray(doc) ? doc : doc && doc.zones;
      if (!Array.isArray(zones)) throw new Error(t("owner.zones.importNoZones"));
    } catch (err) {
      this.importReport.append(el("p", { class: "rest-error", text: t("owner.zones.importUnreadable", { file: file.name, error: err.message || String(err) }) }));
      this.file.value = "";
      return;
    }
    const done = [];
    const failed = [];
    for (const [i, z] of zones.entries()) {
      const name = z && typeof z.name === "string" && z.name ? z.name : t("owner.zones.importNth", { n: i + 1 });
      const msg = { clientmsg: "create", type: "zone", name: z && z.name, points: z && z.points, replace: true };
      if (z && z.capacity !== undefined) msg.capacity = z.capacity;
      if (z && z.wait_at) msg.wait_at = z.wait_at;
      try {
        await this.conn.request(msg);
        done.push(name);
      } catch (err) {
        failed.push([name, describeError(err)]);
      }
    }
    this.file.value = "";
    this.importReport.append(el("p", { text: t("owner.zones.imported", { count: done.length, zones: done.join(", ") || "-" }) }));
    if (failed.length) {
      this.importReport.append(
        el("p", { class: "rest-error", text: t("owner.zones.importFailed", { count: failed.length }) }),
        el("ul", { class: "rest-deps" }, ...failed.map(([n, why]) => el("li", { text: t("owner.zones.importWhy", { zone: n, error: why }) }))),
      );
    }
    toast(t("owner.zones.imported", { count: done.length, zones: done.join(", ") || "-" }), { kind: failed.length ? "error" : "info" });
  }
}
