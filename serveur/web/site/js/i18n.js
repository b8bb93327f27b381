// The pages' words, in the language of the person in front of the screen.
//
// Catalogs are /i18n/<lang>.json (the staff's and shared words), /i18n/guest/<lang>.json (what
// guests read on the robot and table screens), /i18n/owner/<lang>.json (the owner's Restaurant
// and Activity tabs) and /i18n/stats/<lang>.json (the Statistics tab): flat {"key": "text"}
// objects merged per language into one; each set has the same keys in every language, a set's
// keys start with its name (guest., owner., stats.; the main set with none of those), and no key
// is in two sets
// (tests/web/test_i18n.py checks). A text may hold {name} placeholders, and a plural
// text is an object of Intl.PluralRules categories ({"one": "...", "other": "..."}), chosen by
// the `count` parameter. All catalogs are fetched once at start from this page's own server
// (no CDN: restaurants are offline), so switching language later needs no network at all.
//
// The language: `?lang=zh` in the address, else the choice saved on this device for this kind
// of page (staff, robot, table), else the site's default language (the owner's settings, once a
// page that subscribed to them calls applySiteLanguages), else the browser's language, else
// English. The site's settings also narrow the picker to the languages the restaurant offers.
//
// Markup: an element with data-i18n="key" gets its text from the catalog, data-i18n-aria-label,
// data-i18n-title and data-i18n-placeholder set those attributes, data-i18n-args (JSON) gives
// the placeholders' values. They are applied at load and again after every language change;
// anything drawn from live data listens with onLangChange and draws again.

export const LANGS = ["en", "zh", "ms"];
const HTML_LANG = { en: "en", zh: "zh-Hans", ms: "ms" };
const ATTRS = ["aria-label", "title", "placeholder"];

const catalogs = {};
let current = "en";
const listeners = [];
const pluralRules = new Map();

function pageKind() {
  return document.documentElement.dataset.page || "page";
}

function storageKey() {
  return `serveur.lang.${pageKind()}`;
}

/** "zh-CN", "zh_Hans_SG", "ms-MY" -> a supported language, or null. */
export function supported(tag) {
  if (!tag) return null;
  const base = String(tag).toLowerCase().split(/[-_]/)[0];
  return LANGS.includes(base) ? base : null;
}

function saved() {
  try {
    return window.localStorage.getItem(storageKey());
  } catch {
    return null; // storage disabled
  }
}

function save(lang) {
  try {
    window.localStorage.setItem(storageKey(), lang);
  } catch {
    /* storage disabled: the choice lasts until the page is reloaded */
  }
}

/** The language this device asked for: `?lang=` in the address, else its saved choice. */
function chosenLang(loc = window.location) {
  return supported(new URLSearchParams(loc.search).get("lang")) || supported(saved());
}

export function initialLang(loc = window.location) {
  const chosen = chosenLang(loc);
  if (chosen) return chosen;
  for (const tag of navigator.languages || [navigator.language]) {
    const lang = supported(tag);
    if (lang) return lang;
  }
  return "en";
}

// The catalog sets merged for each language: main (staff and shared words), then the others.
const SETS = ["", "guest/", "owner/", "stats/"];

async function fetchCatalog(path) {
  try {
    const reply = await fetch(path);
    if (!reply.ok) throw new Error(`HTTP ${reply.status}`);
    return await reply.json();
  } catch (err) {
    console.warn(`catalog ${path} not loaded: ${err}`);
    return {};
  }
}

async function loadCatalog(lang) {
  const parts = await Promise.all(SETS.map((set) => fetchCatalog(`/i18n/${set}${lang}.json`)));
  catalogs[lang] = Object.assign({}, ...parts);
}

/** The current language ("en", "zh" or "ms"). */
export function lang() {
  return current;
}

export function has(key) {
  return key in (catalogs[current] || {}) || key in (catalogs.en || {});
}

function plural(count) {
  if (!pluralRules.has(current)) pluralRules.set(current, new Intl.PluralRules(HTML_LANG[current]));
  return pluralRules.get(current).select(Number(count));
}

/** The text for `key` in the current language (English if missing there), placeholders filled. */
export function t(key, params = {}) {
  let text = catalogs[current]?.[key] ?? catalogs.en?.[key] ?? key;
  if (text && typeof text === "object") text = text[plural(params.count ?? 0)] ?? text.other ?? key;
  return String(text).replace(/\{(\w+)\}/g, (whole, name) => (name in params ? String(params[name]) : whole));
}

/**
 * A dish as guests and the pass read it: "Laksa", "Laksa ×2", "Laksa ×2 — no chilli".
 * The quantity is shown only above one, so a single dish reads as its name alone.
 */
export function dishLabel(order) {
  const count = Number(order.quantity ?? 1);
  let text = count > 1 ? t("guest.dish.quantity", { dish: order.dish, count }) : String(order.dish);
  if (order.note) text = t("guest.dish.note", { dish: text, note: order.note });
  return text;
}

/** A robot status (the wire value stays English) in the current language. */
export function statusName(status) {
  return has(`status.${status}`) ? t(`status.${status}`) : String(status);
}

/** A role (owner, staff, ...) in the current language. */
export function roleName(role) {
  return has(`role.${role}`) ? t(`role.${role}`) : String(role);
}

/** Apply data-i18n attributes to one element. */
export function translateNode(node) {
  const raw = node.getAttribute("data-i18n-args");
  let args = {};
  if (raw) {
    try {
      args = JSON.parse(raw);
    } catch {
      args = {};
    }
  }
  const key = node.getAttribute("data-i18n");
  if (key) node.textContent = t(key, args);
  for (const attr of ATTRS) {
    const k = node.getAttribute(`data-i18n-${attr}`);
    if (k) node.setAttribute(attr, t(k, args));
  }
}

/** Apply data-i18n attributes to `root` and everything under it. */
export function applyI18n(root = document) {
  const selector = ["[data-i18n]", ...ATTRS.map((a) => `[data-i18n-${a}]`)].join(",");
  if (root.matches && root.matches(selector)) translateNode(root);
  for (const node of root.querySelectorAll(selector)) translateNode(node);
}

/** Call `f(lang)` after every language change (data-i18n markup is already redone then). */
export function onLangChange(f) {
  listeners.push(f);
}

/** Switch language at once: <html lang>, the markup, then every listener. No reload. */
export function setLang(next, { remember = false } = {}) {
  const lang = supported(next) || "en";
  if (remember) {
    save(lang);
    // An address that named a language would bring the old one back on reload: name the new one.
    const url = new URL(window.location.href);
    if (url.searchParams.has("lang")) {
      url.searchParams.set("lang", lang);
      window.history.replaceState(window.history.state, "", url.pathname + url.search + url.hash);
    }
  }
  current = lang;
  document.documentElement.lang = HTML_LANG[lang];
  document.documentElement.dataset.lang = lang;
  applyI18n(document);
  for (const picker of document.querySelectorAll("select.lang-picker")) picker.value = lang;
  for (const f of listeners) {
    try {
      f(lang);
    } catch (err) {
      console.warn(err);
    }
  }
}

// The languages the site offers (its settings; all of them until told).
let offered = [...LANGS];

/** The pickers' options: the languages offered, and the current one if the device chose another. */
function fillPickers() {
  const shown = LANGS.filter((l) => offered.includes(l) || l === current);
  for (const picker of document.querySelectorAll("select.lang-picker")) {
    picker.replaceChildren(
      ...shown.map((l) => {
        const option = document.createElement("option");
        option.value = l;
        option.lang = HTML_LANG[l];
        option.setAttribute("data-i18n", `lang.${l}`);
        translateNode(option);
        return option;
      }),
    );
    picker.value = current;
  }
}

/** Fill every <select class="lang-picker"> with the languages, each named in itself. */
function setupPickers() {
  fillPickers();
  for (const picker of document.querySelectorAll("select.lang-picker")) {
    picker.addEventListener("change", () => setLang(picker.value, { remember: true }));
  }
}

/**
 * Obey the site's settings (the `settings` topic's record): the pickers offer only its
 * `languages`, and a device that chose nothing (no `?lang=`, nothing saved) speaks its
 * `language`. A device's own choice still wins.
 */
export function applySiteLanguages(settings) {
  if (!settings || !Array.isArray(settings.languages)) return;
  const langs = settings.languages.filter((l) => LANGS.includes(l));
  offered = langs.length ? langs : [...LANGS];
  document.documentElement.dataset.siteLangs = offered.join(" "); // the site's word is in
  const fallback = supported(settings.language) || offered[0];
  const next = chosenLang() || (offered.includes(fallback) ? fallback : offered[0]);
  if (next !== current) setLang(next);
  fillPickers();
}

await Promise.all(LANGS.map(loadCatalog));
setupPickers();
setLang(initialLang());
