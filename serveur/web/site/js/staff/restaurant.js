// Restaurant (the owner's): the robots (address, ROS, drive, home, charger, trays, status, why the
// server cannot reach one; edit, remove), the tables and places (add, rename, move, remove after
// seeing what depends on them), the zones robots take turns through, the Wi-Fi call buttons, the
// orders from the till (till/setup.js: the `till` verb), and the site's settings (time at a table, trays, leaving without Go, the languages the pages
// offer, calls, plates, charging, cruising). Everything goes through the
// protocol's `site` verb (the server refuses anyone but an owner), `create waypoint` and
// `create zone` with `replace`.
//
// This module is the panel: it lays out the sections (restaurant/robots.js, places.js, zones.js,
// buttons.js, settings.js, map.js, plan.js, align.js, backups.js, ../till/setup.js, and chain.js:
// the chain's head office, read with the `chain` verb while the tab is shown) and keeps them
// live. It also follows the `settings` topic (every role may read it): the language pickers
// offer the site's languages and a device with no choice of its own speaks the site's default.

import { el, showError } from "../ui.js";
import { applySiteLanguages, onLangChange } from "../i18n.js";
import { PlacesSection } from "./restaurant/places.js";
import { RobotsSection } from "./restaurant/robots.js";
import { SettingsSection } from "./restaurant/settings.js";
import { ZonesSection } from "./restaurant/zones.js";
import { MapSection } from "./restaurant/map.js";
import { PlanSection } from "./restaurant/plan.js";
import { BackupsSection } from "./restaurant/backups.js";
import { AlignSection } from "./restaurant/align.js";
import { ButtonsSection } from "./restaurant/buttons.js";
import { TillSection } from "./till/setup.js";
import { ChainSection } from "./restaurant/chain.js";

export class RestaurantPanel {
  constructor(root, conn, live) {
    this.root = root;
    this.conn = conn;
    this.live = live;
    this.robots = new RobotsSection(conn, live, () => this.settings.siteTrays());
    this.places = new PlacesSection(conn, live);
    this.zones = new ZonesSection(conn, live);
    this.buttons = new ButtonsSection(conn, live);
    this.till = new TillSection(conn, live);
    // The site's trays changed: each robot's row says how many it has.
    this.settings = new SettingsSection(conn, () => {
      this.robots.rows.invalidate();
      this.render();
    });

    this.map = new MapSection(conn);
    this.plan = new PlanSection(conn);
    this.align = new AlignSection(conn, live);
    this.backups = new BackupsSection(conn);
    this.chain = new ChainSection(conn, live, root);
    root.append(
      el(
        "div",
        { class: "rest-grid" },
        this.chain.section,
        this.robots.section,
        this.places.section,
        this.zones.section,
        this.buttons.section,
        this.till.section,
        this.settings.section,
        this.map.section,
        this.plan.section,
        this.align.section,
        this.backups.section,
      ),
    );

    conn.subscribe(["settings"]);
    live.addEventListener("change", (e) => {
      const topic = e.detail.topic;
      if (topic === "robots" || topic === "waypoints" || topic === "zones" || topic === "leases") this.render();
      if (topic === "map") this.align.mapChanged();
      if (topic === "settings") {
        applySiteLanguages(live.settings);
        this.settings.got(live.settings);
      }
    });
    onLangChange(() => {
      this.robots.rows.invalidate();
      this.places.rows.invalidate();
      this.zones.rows.invalidate();
      this.backups.rows.invalidate();
      this.buttons.rows.invalidate();
      this.buttons.fillKinds();
      this.till.fillCodePages();
      this.settings.fillLanguage();
      this.chain.render();
      this.render();
    });
    this.settings.fillLanguage();
    this.render();
  }

  /** The tab was opened: the lists are live; read the settings afresh. */
  async shown() {
    this.render();
    this.backups.load();
    this.chain.load();
    this.buttons.load();
    this.till.load();
    try {
      const reply = await this.conn.request({ clientmsg: "site", action: "settings" });
      this.settings.got(reply.settings); // a form the owner began filling meanwhile is kept
    } catch (err) {
      if (err && err.code !== "forbidden") showError(err);
    }
  }

  render() {
    this.robots.render();
    this.places.render();
    this.zones.render();
    this.buttons.render();
  }
}
