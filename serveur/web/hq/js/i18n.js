// The dashboard's words, in the language of the person reading it.
//
// Catalogs are /i18n/<lang>.json: flat {"key": "text"} objects with the same keys in every
// language (tests/web/test_hq_ui.py checks). A text may hold {name} placeholders; a plural text
// is an object of Intl.PluralRules categories ({"one": "...", "other": "..."}) chosen by the
// `count` parameter. Every catalog is fetched once at start from the centre itself (no CDN), so
// switching language later needs no network.
//
// The language: `?lang=fr` in the address, else the choice saved on this device, else the
// browser's language, else English. Markup: data-i18n="key" sets an element's text,
// data-i18n-aria-label / -title / -placeholder set those attributes; anything drawn from data
// listens with onLangChange and draws again.

export const LANGS = ["en", "fr", "ms"];
const HTML_LANG = { en: "en", fr: "fr", ms: "ms" };
const ATTRS = ["aria-label", "title", "placeholder"];
const STORAGE = "serveur.lang.hq";

const catalogs = {};
const listeners = [];
const plurals = new Map();
let current = "en";

/** "fr-CA", "ms_MY" -> a language of the dashboard, or null. */
export function supported(tag) {
  if (!tag) return null;
  const base = String(tag).toLowerCase().split(/[-_]/)[0];
  return LANGS.includes(base) ? base : null;
}

function saved() {
  try {
    return window.localStorage.getItem(STORAGE);
  } catch {
    return null; // storage disabled
  }
}

function save(lang) {
  try {
    window.localStorage.setItem(STORAGE, lang);
  } catch {
    /* storage disabled: the choice lasts until the page is reloaded */
  }
}

function initialLang() {
  const asked = supported(new URLSearchParams(window.location.search).get("lang")) || supported(saved());
  if (asked) return asked;
  for (const tag of navigator.languages || [navigator.language]) {
    const found = supported(tag);
    if (found) return found;
  }
  return "en";
}

async function loadCatalog(lang) {
  try {
    const reply = await fetch(`/i18n/${lang}.json`);
    if (!reply.ok) throw new Error(`HTTP ${reply.status}`);
    catalogs[lang] = await reply.json();
  } catch (err) {
    console.warn(`catalog ${lang} not loaded: ${err}`);
    catalogs[lang] = {};
  }
}

/** The current language ("en", "fr", "ms"). */
export function lang() {
  return current;
}

/** The BCP 47 tag for Intl and <html lang>. */
export function locale() {
  return HTML_LANG[current] || "en";
}

export function has(key) {
  return key in (catalogs[current] || {}) || key in (catalogs.en || {});
}

function plural(count) {
  if (!plurals.has(current)) plurals.set(current, new Intl.PluralRules(locale()));
  return plurals.get(current).select(Number(count));
}

/** The text for `key` in the current language (English if missing there), placeholders filled. */
export function t(key, params = {}) {
  let text = catalogs[current]?.[key] ?? catalogs.en?.[key] ?? key;
  if (text && typeof text === "object") text = text[plural(params.count ?? 0)] ?? text.other ?? key;
  return String(text).replace(/\{(\w+)\}/g, (whole, name) => (name in params ? String(params[name]) : whole));
}

export function translateNode(node) {
  const key = node.getAttribute("data-i18n");
  if (key) node.textContent = t(key);
  for (const attr of ATTRS) {
    const k = node.getAttribute(`data-i18n-${attr}`);
    if (k) node.setAttribute(attr, t(k));
  }
}

export function applyI18n(root = document) {
  const selector = ["[data-i18n]", ...ATTRS.map((a) => `[data-i18n-${a}]`)].join(",");
  for (const node of root.querySelectorAll(selector)) translateNode(node);
}

/** Call `f(lang)` after every language change (the markup's words are redone by then). */
export function onLangChange(f) {
  listeners.push(f);
}

export function setLang(next, { remember = false } = {}) {
  current = supported(next) || "en";
  if (remember) save(current);
  document.documentElement.lang = locale();
  document.documentElement.dataset.lang = current;
  applyI18n(document);
  for (const picker of document.querySelectorAll("select.lang-picker")) picker.value = current;
  for (const f of listeners) {
    try {
      f(current);
    } catch (err) {
      console.warn(err);
    }
  }
}

/** Each <select class="lang-picker"> lists the languages, each named in itself. */
function setupPickers() {
  for (const picker of document.querySelectorAll("select.lang-picker")) {
    picker.replaceChildren(
      ...LANGS.map((l) => {
        const option = document.createElement("option");
        option.value = l;
        option.lang = HTML_LANG[l];
        option.textContent = catalogs[l]?.[`lang.${l}`] || l;
        return option;
      }),
    );
    picker.addEventListener("change", () => setLang(picker.value, { remember: true }));
  }
}

await Promise.all(LANGS.map(loadCatalog));
setupPickers();
setLang(initialLang());
