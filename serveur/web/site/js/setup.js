// The first-run setup page (setup.html#setup=CODE): the owner, on a tablet, chooses their
// password (the code in the link the server printed at its first start creates the owner once:
// `login` with `setup`), then the restaurant's name, languages and the address its tablets
// reach it at (`site set_settings`: every screen's setup link and QR code uses it), the robots
// (each address tested live), the places on the map (setup/places.js) and one test trip
// (setup/trip.js), then goes on to the console. Each step can be left and resumed: after the
// first the page is logged in as the owner (the session token is kept like the console's), and
// opening it again shows the first step not done yet, filled with what was saved.

import { describeError } from "./ui.js";
import { Connection, loadToken } from "./ws.js";
import { Live } from "./live.js";
import { onLangChange, t } from "./i18n.js";
import { say, show } from "./setup/steps.js";
import { PlacesStep, placesState } from "./setup/places.js";
import { TripStep } from "./setup/trip.js";

const code = setupCode();
const conn = new Connection();
const live = new Live(conn);
let settings = null;

function setupCode() {
  const m = /(?:^#|&)setup=([^&]+)/.exec(window.location.hash);
  if (!m) return null;
  // Out of the address bar and the history: a code is used once.
  window.history.replaceState(null, "", window.location.pathname + window.location.search);
  return decodeURIComponent(m[1]);
}

// -- step 1: the owner -------------------------------------------------------------------------

document.getElementById("owner-form").addEventListener("submit", (e) => {
  e.preventDefault();
  const username = document.getElementById("owner-name").value.trim();
  const password = document.getElementById("owner-password").value;
  if (!username) return say("setup.owner.needName");
  if (password.length < 8) return say("setup.owner.tooShort");
  if (password !== document.getElementById("owner-repeat").value) return say("setup.owner.differ");
  say(null);
  conn.login({ setup: code, username, password });
});

// -- step 2: the restaurant ---------------------------------------------------------------------

const form = document.getElementById("restaurant-form");
const languageSelect = document.getElementById("restaurant-language");

function chosenLanguages() {
  return [...form.querySelectorAll('input[name="languages"]:checked')].map((b) => b.value);
}

function fillLanguages(selected) {
  const langs = chosenLanguages();
  languageSelect.replaceChildren(
    ...langs.map((l) => {
      const o = document.createElement("option");
      o.value = l;
      o.textContent = t(`lang.${l}`);
      return o;
    }),
  );
  languageSelect.value = langs.includes(selected) ? selected : langs[0] || "";
}
form.addEventListener("change", (e) => {
  if (e.target.name === "languages") fillLanguages(languageSelect.value);
});

function fillRestaurant(s) {
  document.getElementById("restaurant-name").value = s.name || "";
  for (const box of form.querySelectorAll('input[name="languages"]')) box.checked = s.languages.includes(box.value);
  fillLanguages(s.language);
  // The address this tablet used is the best first guess (not 127.0.0.1: a tablet opened it).
  document.getElementById("restaurant-address").value = s.public_url || window.location.origin;
}

form.addEventListener("submit", async (e) => {
  e.preventDefault();
  const name = document.getElementById("restaurant-name").value.trim();
  const languages = chosenLanguages();
  const address = document.getElementById("restaurant-address").value.trim().replace(/\/+$/, "");
  if (!name) return say("setup.restaurant.needName");
  if (!languages.length) return say("setup.restaurant.needLanguage");
  if (!/^https?:\/\/[^\s/#?@]+$/.test(address)) return say("setup.restaurant.badAddress");
  say(null);
  try {
    const reply = await conn.request({
      clientmsg: "site",
      action: "set_settings",
      name,
      languages,
      language: languageSelect.value,
      public_url: address,
    });
    settings = reply.settings;
    show("robots");
  } catch (err) {
    say("setup.failed", { message: describeError(err) });
  }
});

// -- step 3: the robots ---------------------------------------------------------------------------

const robotForm = document.getElementById("robot-form");
const found = document.getElementById("robot-found");
const addBtn = document.getElementById("robot-add");
let tested = null; // {url, ros} of the last address found reachable

/** The robot's rosbridge address as typed, completed: a bare host or IP (what a robot's label
 *  or its maker's sheet usually gives) becomes ws://HOST:9090, rosbridge's default port. */
function robotAddress() {
  const input = document.getElementById("robot-address");
  let url = input.value.trim();
  if (url && !/^[a-z]+:\/\//i.test(url)) url = `ws://${url}`;
  const m = /^(wss?:\/\/)([^\s/#?:]+|\[[0-9a-f:]+\])(:\d+)?(\/.*)?$/i.exec(url);
  if (m && !m[3]) url = `${m[1]}${m[2]}:9090${m[4] || ""}`;
  if (url !== input.value.trim()) input.value = url; // shown as it will be used
  return url;
}

document.getElementById("robot-address").addEventListener("input", () => {
  tested = null;
  addBtn.disabled = true;
});

document.getElementById("robot-test").addEventListener("click", async () => {
  const url = robotAddress();
  say(null);
  if (!/^wss?:\/\/[^\s/#?]+/.test(url)) {
    found.textContent = t("setup.robots.badAddress"); // beside the button just pressed
    return;
  }
  found.textContent = t("setup.robots.testing");
  try {
    const p = (await conn.request({ clientmsg: "site", action: "probe_robot", url })).probe;
    if (!p.reachable) {
      found.textContent = t("setup.robots.notFound", { why: p.why });
      return;
    }
    tested = { url, ros: p.ros };
    addBtn.disabled = false;
    found.textContent = p.ros
      ? t("setup.robots.found", { ros: p.ros === 2 ? "ROS 2" : "ROS 1", nav: p.navigation || t("setup.robots.noNav") })
      : t("setup.robots.foundUnknown");
  } catch (err) {
    found.textContent = t("setup.failed", { message: describeError(err) });
  }
});

robotForm.addEventListener("submit", async (e) => {
  e.preventDefault();
  const name = document.getElementById("robot-name").value.trim();
  if (!tested || tested.url !== robotAddress()) return say("setup.robots.needTest");
  if (!name) return say("setup.robots.needName");
  say(null);
  const msg = { clientmsg: "create", type: "robot", name, url: tested.url };
  if (tested.ros === 2) msg.link = { ros: "2" };
  try {
    await conn.request(msg);
    const item = document.createElement("li");
    item.textContent = t("setup.robots.added", { name });
    document.getElementById("robots-added").append(item);
    found.textContent = "";
    tested = null;
    addBtn.disabled = true;
    document.getElementById("robot-address").value = "";
    const next = name.match(/^(.*?)(\d+)$/);
    document.getElementById("robot-name").value = next ? `${next[1]}${Number(next[2]) + 1}` : "";
  } catch (err) {
    say("setup.failed", { message: describeError(err) });
  }
});

document.getElementById("robots-done").addEventListener("click", () => show("places"));

// -- steps 4 and 5: the places, a test trip ------------------------------------------------------

new PlacesStep(conn, live);
new TripStep(conn, live);
// Every robot's pose, live on the map (as the console follows them).
live.addEventListener("change", (e) => {
  if (e.detail.topic === "robots") conn.subscribe([...live.robots.keys()].map((n) => `pose:${n}`));
});

// -- the connection -------------------------------------------------------------------------------

conn.addEventListener("login", (e) => {
  // Not logged in: a setup code makes the owner; without one, this restaurant is set up
  // already (or the link was not the newest): the console's login is the way in.
  const err = e.detail.error;
  if (err) say("setup.failed", { message: describeError(err) });
  else if (!code) say("setup.noCode");
  show("owner");
  document.getElementById("owner-form").hidden = !code;
});

// Online (after the session: the "state" event follows it): as the owner, the first step not
// done, once the live state's first snapshot is in. Only once: a reconnect (the Wi-Fi blinked)
// must not refill a form being typed in, nor move the owner to another step.
let resumed = false;
conn.addEventListener("state", async (e) => {
  if (e.detail.state !== "online" || !conn.session || resumed) return;
  if (conn.session.role !== "owner") {
    say("setup.notOwner");
    return;
  }
  say(null);
  const reply = await conn.request({ clientmsg: "site", action: "settings" });
  // The site's languages are not applied here: the owner keeps the language they chose for
  // this page, whatever default they give the screens.
  settings = reply.settings;
  fillRestaurant(settings);
  conn.subscribe(["robots", "waypoints", "map", "tasks", "orders", "settings"]);
});
conn.addEventListener("snapshot", (e) => {
  if (resumed || !settings || !("robots" in e.detail.data)) return;
  resumed = true;
  if (!(settings.name && settings.public_url)) show("restaurant");
  else if (!live.robots.size) show("robots");
  else if (!placesState(live).ready) show("places");
  else show("trip");
});

onLangChange(() => settings && fillLanguages(languageSelect.value));
if (!code && !loadToken()) say("setup.noCode");
show("owner");
conn.start();
