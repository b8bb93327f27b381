// The staff console: wires the connection, the live state and the console's panels.

import { keep, kept } from "../keep.js";
import { Connection } from "../ws.js";
import { Live } from "../live.js";
import { el, guardOffline, showError, watchConnection } from "../ui.js";
import { MapView } from "../map/view.js";
import { RobotsPanel } from "./robots.js";
import { MapTools } from "./maptools.js";
import { Teleop } from "./teleop.js";
import { CameraView } from "./camera.js";
import { WaypointsPanel } from "./waypoints.js";
import { IssuePanel } from "./issue.js";
import { NewOrderPanel } from "./neworder.js";
import { RegisterRobot } from "./register.js";
import { PlatesButton } from "./plates.js";
import { KitchenPanel } from "./kitchen.js";
import { MenuPanel } from "./menu.js";
import { AccountsPanel } from "./accounts.js";
import { AlertsPanel } from "./alerts.js";
import { CallsPanel } from "./calls.js";
import { RestaurantPanel } from "./restaurant.js";
import { StatsPanel } from "./stats.js";
import { LogPanel } from "./log.js";
import { onLangChange, roleName, t } from "../i18n.js";

const conn = new Connection();
const live = new Live(conn);
watchConnection(conn);
guardOffline(conn);

// Who is logged in, and the way out (a shared tablet at the pass changes hands).
const who = el("span", { class: "who muted", "data-testid": "who" });
const logout = el("button", { class: "logout", type: "button", "data-i18n": "staff.logout" });
document.querySelector(".topbar").append(who, logout);
const showWho = () => {
  const s = conn.session;
  if (!s) return;
  who.textContent = s.user ? t("staff.who", { user: s.user, role: roleName(s.role) }) : roleName(s.role);
  // The menu and the accounts are the owner's: their tabs show only in an owner's session.
  const owner = s.role === "owner";
  for (const id of ["tab-menu", "tab-accounts", "tab-restaurant", "tab-stats", "tab-log"]) {
    const tab = document.getElementById(id);
    tab.hidden = !owner;
    if (!owner && tab.getAttribute("aria-selected") === "true") document.getElementById("tab-map").click();
  }
  if (owner) accounts.refresh();
  openLinked();
  restoreTab();
};
conn.addEventListener("session", showWho);
onLangChange(showWho);
logout.addEventListener("click", () => conn.logout().catch(showError));

// Which robot the map's scan, the tools, teleop and waypoints act on. Its laser scan streams
// only while the map is shown on a visible page (a tablet on another tab or asleep would pull
// ~6 kB/s for nothing).
let scanTopic = null;
function streamScan() {
  const mapShown = document.getElementById("tab-map").getAttribute("aria-selected") === "true";
  const want = selection.name && mapShown && document.visibilityState === "visible" ? `scan:${selection.name}` : null;
  if (want === scanTopic) return;
  if (scanTopic) conn.unsubscribe([scanTopic]);
  if (want) conn.subscribe([want]);
  scanTopic = want;
}
document.addEventListener("visibilitychange", streamScan);
const selection = {
  name: null,
  listeners: [],
  set(name) {
    if (name === this.name) return;
    this.name = name;
    streamScan();
    this.listeners.forEach((f) => f(name));
  },
  onChange(f) {
    this.listeners.push(f);
  },
};

const TAB_KEY = "serveur.keep.tab"; // the tab open, kept across a reload (keep.js)
let restored = false; // the kept tab was brought back (restoreTab): tabs opened now are kept
const goals = new Map(); // robot -> the last goal this console sent, drawn until it is reached

let tools = null; // the map's toolbar, made once the view exists
const view = new MapView(document.getElementById("map"), live, {
  selected: () => selection.name,
  goals: () => goals,
  onSelect: (name) => selection.set(name),
  onPose: (tool, pose) => tools.posePicked(tool, pose),
  onCancel: () => tools.cancel(),
  onCursor: (mark) => tools && tools.showMark(mark),
});
tools = new MapTools(conn, live, view, selection, goals);
new RobotsPanel(document.getElementById("robots"), conn, live, selection);
new PlatesButton(document.getElementById("robot-modes"), conn, live);
new RegisterRobot(document.getElementById("register"), conn, live);
new Teleop(document.getElementById("teleop"), conn, live, selection, new CameraView(conn, live, selection));
new WaypointsPanel(document.getElementById("waypoints"), conn, live, selection);
new CallsPanel(document.getElementById("panel-calls"), document.getElementById("tab-calls"), conn, live);
new IssuePanel(document.getElementById("panel-issue"), conn, live);
const newOrder = new NewOrderPanel(document.getElementById("panel-order"), conn, live);
// A ticket from the till nobody understood: its dishes are added by hand in New order.
const kitchen = new KitchenPanel(document.getElementById("panel-kitchen"), conn, live, {
  addByHand: (table) => {
    document.getElementById("tab-order").click();
    newOrder.startFor(table);
  },
});
// The till's tickets stream to the Kitchen tab only while it is shown on a visible page.
const followTickets = () => {
  const shown = document.getElementById("tab-kitchen").getAttribute("aria-selected") === "true";
  kitchen.shown(shown && document.visibilityState === "visible");
};
document.addEventListener("visibilitychange", followTickets);
new MenuPanel(document.getElementById("panel-menu"), conn, live);
const accounts = new AccountsPanel(document.getElementById("panel-accounts"), conn, live);
// The owner's other tabs: each has shown(), called when its tab is opened (they load on demand).
const ownerPanels = {
  "tab-restaurant": new RestaurantPanel(document.getElementById("panel-restaurant"), conn, live),
  "tab-stats": new StatsPanel(document.getElementById("panel-stats"), conn, live),
  "tab-log": new LogPanel(document.getElementById("panel-log"), conn, live),
};
new AlertsPanel(
  {
    banner: document.getElementById("alerts"),
    badge: document.getElementById("alert-badge"),
    mute: document.getElementById("alert-mute"),
  },
  conn,
  live,
);

live.addEventListener("change", (e) => {
  const topic = e.detail.topic;
  if (topic === "robots") {
    // Every robot's pose is drawn live: follow the pose stream of each robot we learn of.
    conn.subscribe([...live.robots.keys()].map((n) => `pose:${n}`));
    if (!selection.name && live.robots.size) selection.set([...live.robots.keys()][0]);
  }
  // Only what the map shows: a new order or an alert does not redraw it.
  const [kind, robot] = topic.split(":");
  const selectedStream = (kind === "scan" || kind === "cloud") && robot === selection.name;
  const drawn = ["robots", "tasks", "waypoints", "map"].includes(topic) || kind === "pose" || selectedStream;
  if (drawn) view.requestDraw();
});

const showSelected = (name) => {
  document.getElementById("selected-title").textContent = name ? t("selected.named", { name }) : t("selected.title");
  document.getElementById("selected-note").hidden = Boolean(name);
};
selection.onChange((name) => {
  showSelected(name);
  view.requestDraw();
});
onLangChange(() => {
  showSelected(selection.name);
  view.requestDraw(); // the canvas's own words
});

setupTabs();
conn.subscribe(["robots", "orders", "tasks", "waypoints", "map", "alerts", "menu", "blocks"]);
conn.start();

// A link into the console names a tab and, within it, a section: `/#restaurant/plan` opens the
// Restaurant tab at "Map from the floor plan" (the setup page sends the owner there). An owner's
// tab shows once the session says who is logged in, so the link is followed then.
let followed = ""; // the link followed already: a later session event or language leaves it
function openLinked() {
  const hash = window.location.hash;
  let name, section;
  try {
    [name, section] = decodeURIComponent(hash.slice(1)).split("/");
  } catch {
    return; // a malformed link: the page stays as it is
  }
  const tab = name && /^[a-z]+$/.test(name) ? document.getElementById(`tab-${name}`) : null;
  if (!tab || tab.hidden || hash === followed) return;
  followed = hash;
  if (tab.getAttribute("aria-selected") !== "true") tab.click();
  const title = section && /^[a-z]+$/.test(section) ? document.getElementById(`rest-${section}-title`) : null;
  if (title) title.closest("section").scrollIntoView({ block: "start" });
}
window.addEventListener("hashchange", openLinked);

// The tab open before a reload comes back (once, when the session says which tabs this person
// has), unless a link named one.
function restoreTab() {
  if (restored) return;
  restored = true;
  if (followed) return;
  const id = kept(TAB_KEY);
  const tab = typeof id === "string" && /^tab-[a-z]+$/.test(id) ? document.getElementById(id) : null;
  if (tab && !tab.hidden && tab.getAttribute("aria-selected") !== "true") tab.click();
}

function setupTabs() {
  const tabs = [...document.querySelectorAll('[role="tab"]')];
  const show = (tab) => {
    for (const t of tabs) {
      const on = t === tab;
      t.setAttribute("aria-selected", String(on));
      t.tabIndex = on ? 0 : -1;
      document.getElementById(t.getAttribute("aria-controls")).hidden = !on;
    }
    if (tab.id === "tab-map") view.requestDraw();
    streamScan();
    if (tab.id === "tab-accounts") accounts.refresh();
    followTickets();
    if (ownerPanels[tab.id]) ownerPanels[tab.id].shown();
    if (restored) keep(TAB_KEY, tab.id);
    tab.scrollIntoView({ block: "nearest", inline: "nearest" }); // a phone's tab row scrolls
  };
  tabs.forEach((t) => t.addEventListener("click", () => show(t)));
  // Arrow keys move between tabs (the WAI-ARIA tabs pattern).
  document.querySelector('[role="tablist"]').addEventListener("keydown", (e) => {
    const shown = tabs.filter((t) => !t.hidden);
    const i = shown.indexOf(document.activeElement);
    if (i < 0 || (e.key !== "ArrowRight" && e.key !== "ArrowLeft")) return;
    const next = shown[(i + (e.key === "ArrowRight" ? 1 : shown.length - 1)) % shown.length];
    next.focus();
    show(next);
  });
  show(tabs[0]);
}
