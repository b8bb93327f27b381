// The chain's dashboard (serveur hq): a login, then every site at a glance (polled every 5 s
// while shown, each card drawn again only when it changed), the sites compared day by day
// (fetched only while that tab is open), and one site's figures and trips. Read-only: a
// command goes to the site's own console.
//
// Where you are is in the address (#/, #/compare, #/site/<name>), so the browser's Back works
// and a reload stays put; the login lasts as long as this browser tab (sessionStorage).

import { onLangChange, t } from "./i18n.js";
import { LoggedOut, forget, get, logIn, session } from "./api.js";
import { say } from "./dom.js";
import { clock } from "./format.js";
import { Compare } from "./compare.js";
import { Overview } from "./overview.js";
import { SitePage } from "./site.js";

const POLL_MS = 5000;

const $ = (id) => document.getElementById(id);
const body = document.body;
const loginBox = $("login");
const loginForm = $("login-form");
const loginWhy = $("login-why");
const nameInput = $("login-name");
const passwordInput = $("login-password");
const loginButton = $("login-submit");
const app = $("app");
const tabs = [$("tab-overview"), $("tab-compare")];
const panels = { overview: $("panel-overview"), compare: $("panel-compare"), site: $("panel-site") };
const net = $("net");
const overviewState = $("overview-state");
const updated = $("overview-updated");

const siteHref = (site) => `#/site/${encodeURIComponent(site)}`;
const overview = new Overview($("cards"), { href: siteHref });
const compare = new Compare(panels.compare, { onLoggedOut: () => loggedOut() });
const sitePage = new SitePage(panels.site, { onLoggedOut: () => loggedOut(), back: () => goBack() });

let view = null; // "login", "overview", "compare", "site"
let lastSite = null; // the site whose page was open: its card takes the focus back
let lastReply = null;
let pollTimer = 0;
let pollSeq = 0;
let polling = false;

// -- the overview's polling: only while it is shown and the page is visible --------------------

function wantPolling() {
  return view === "overview" && document.visibilityState !== "hidden";
}

async function poll() {
  clearTimeout(pollTimer);
  const seq = ++pollSeq;
  try {
    const reply = await get("/api/sites");
    if (seq !== pollSeq) return;
    lastReply = reply;
    say(net, "");
    overview.update(reply);
    say(overviewState, reply.sites.length ? overview.summary() : t("overview.none"));
    updated.textContent = t("overview.updated", { time: clock(reply.now, reply.now) });
    body.dataset.polls = String(Number(body.dataset.polls || 0) + 1);
  } catch (err) {
    if (seq !== pollSeq) return;
    if (err instanceof LoggedOut) return loggedOut();
    say(net, t("net.down"));
  }
  if (polling) pollTimer = setTimeout(poll, POLL_MS);
}

function startPolling() {
  if (polling || !wantPolling()) return;
  polling = true;
  poll();
}

function stopPolling() {
  polling = false;
  clearTimeout(pollTimer);
  pollSeq++;
}

document.addEventListener("visibilitychange", () => (wantPolling() ? startPolling() : stopPolling()));

// -- where we are --------------------------------------------------------------------------------

function route() {
  if (!session()) return showLogin();
  const hash = window.location.hash;
  if (hash.startsWith("#/site/")) return show("site", decodeURIComponent(hash.slice(7)));
  if (hash === "#/compare") return show("compare");
  return show("overview");
}

function show(next, site) {
  const was = view;
  view = next;
  body.dataset.view = next;
  loginBox.hidden = true;
  app.hidden = false;
  $("logout").hidden = false;
  $("tabs").hidden = next === "site";
  for (const [name, panel] of Object.entries(panels)) panel.hidden = name !== next;
  for (const tab of tabs) {
    const on = tab.getAttribute("aria-controls") === `panel-${next}`;
    tab.setAttribute("aria-selected", String(on));
    tab.tabIndex = on ? 0 : -1;
  }
  if (next === "compare") compare.shown();
  else compare.hidden();
  if (next === "site") {
    lastSite = site;
    sitePage.show(site, lastReply?.sites.find((s) => s.site === site));
    $("site-title").focus();
  } else sitePage.hidden();
  if (next === "overview") {
    startPolling();
    if (was === "site" && lastSite) overview.cards.get(lastSite)?.node.querySelector("a")?.focus();
  } else stopPolling();
}

function goBack() {
  window.location.hash = "#/";
}

function showLogin(why = "") {
  view = "login";
  body.dataset.view = "login";
  stopPolling();
  compare.hidden();
  sitePage.hidden();
  app.hidden = true;
  $("logout").hidden = true;
  loginBox.hidden = false;
  loginWhy.dataset.why = why;
  say(loginWhy, why ? t(why) : "");
  (nameInput.value ? passwordInput : nameInput).focus();
}

/** The centre refused our token (it expired, or the centre restarted): log in again. */
function loggedOut() {
  forget();
  showLogin("login.expired");
}

window.addEventListener("hashchange", route);

// -- login ---------------------------------------------------------------------------------------

loginForm.addEventListener("submit", async (e) => {
  e.preventDefault();
  const name = nameInput.value.trim();
  const password = passwordInput.value;
  if (!name || !password) {
    loginWhy.dataset.why = "login.missing";
    say(loginWhy, t("login.missing"));
    (name ? passwordInput : nameInput).focus();
    return;
  }
  loginButton.disabled = true;
  loginButton.textContent = t("login.busy");
  const result = await logIn(name, password);
  loginButton.disabled = false;
  loginButton.textContent = t("login.submit");
  if (result === true) {
    passwordInput.value = "";
    say(loginWhy, "");
    route();
    $("tab-overview").focus();
    return;
  }
  const why = result === "wrong" ? "login.wrong" : "login.unreachable";
  loginWhy.dataset.why = why;
  say(loginWhy, t(why));
  passwordInput.select();
  passwordInput.focus();
});

$("logout").addEventListener("click", () => {
  forget();
  lastReply = null;
  window.location.hash = "#/";
  showLogin();
});

// -- tabs: click, or the arrow keys, Home and End --------------------------------------------------

for (const tab of tabs) {
  tab.addEventListener("click", () => {
    window.location.hash = tab.id === "tab-compare" ? "#/compare" : "#/";
  });
  tab.addEventListener("keydown", (e) => {
    const i = tabs.indexOf(tab);
    const to = { ArrowRight: i + 1, ArrowLeft: i - 1, Home: 0, End: tabs.length - 1 }[e.key];
    if (to === undefined) return;
    e.preventDefault();
    const next = tabs[(to + tabs.length) % tabs.length];
    next.focus();
    next.click();
  });
}

// -- language ------------------------------------------------------------------------------------

onLangChange(() => {
  document.title = t("doc.title");
  if (loginWhy.dataset.why && !loginWhy.hidden) say(loginWhy, t(loginWhy.dataset.why));
  loginButton.textContent = t("login.submit");
  if (lastReply) {
    overview.invalidate();
    overview.update(lastReply);
    say(overviewState, lastReply.sites.length ? overview.summary() : t("overview.none"));
    updated.textContent = t("overview.updated", { time: clock(lastReply.now, lastReply.now) });
  }
  if (net.textContent) say(net, t("net.down"));
  compare.render();
  sitePage.render();
});

document.title = t("doc.title");
route();
