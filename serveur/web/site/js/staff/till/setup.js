// The Restaurant tab's Till section (issue 33): orders straight from the restaurant's till. The
// till prints each kitchen ticket to a network printer; serveur listens as a printer on its
// printer port, and either passes every ticket on to the kitchen printer (its address given) or
// is a second printer the till prints to (no address). The section has three parts:
//
// - the printer: the port (0: off), the kitchen printer's address, the printer's code page,
//   saved with `till setup`, and how it stands now in words (the `till` topic: listening or
//   not, the kitchen printer answering or not, why the port could not open);
// - how to read the tickets (pattern.js): the owner marks the lines of one kept ticket, sees how
//   every kept ticket reads, and saves;
// - the till's names for the menu's dishes (names.js).

import { act, el, toast } from "../../ui.js";
import { t } from "../../i18n.js";
import { field } from "../forms.js";
import { PatternSetup } from "./pattern.js";
import { MenuNames } from "./names.js";

const TOPIC = "till";
export const CODE_PAGES = {
  auto: "owner.till.codePage.auto",
  cp437: "owner.till.codePage.cp437",
  cp850: "owner.till.codePage.cp850",
  cp1252: "owner.till.codePage.cp1252",
  gb18030: "owner.till.codePage.gb18030",
  "utf-8": "owner.till.codePage.utf8",
};

/** The till's state in words: the printer port, then the kitchen printer. */
function stateWords(s) {
  let port;
  if (s.listening) port = t("owner.till.state.listening", { port: s.port });
  else if (!s.port) port = t("owner.till.state.off");
  else if (s.error) port = t("owner.till.state.error", { port: s.port, error: s.error });
  else port = t("owner.till.state.opening", { port: s.port });
  let printer;
  if (!s.printer) printer = t("owner.till.state.second");
  else if (s.printer_up === true) printer = t("owner.till.state.printerUp", { printer: s.printer });
  else if (s.printer_up === false) printer = t("owner.till.state.printerDown", { printer: s.printer });
  else printer = t("owner.till.state.printerUntried", { printer: s.printer });
  const pattern = s.pattern ? t("owner.till.state.pattern") : t("owner.till.state.noPattern");
  return { port, printer, pattern, trouble: Boolean((s.port && !s.listening && s.error) || s.printer_up === false) };
}

/** A field's hint, read with it (aria-describedby). */
function hint(id, key) {
  return el("p", { id, class: "muted rest-hint", "data-i18n": key });
}

export class TillSection {
  constructor(conn, live) {
    this.conn = conn;
    this.state = null; // TillState, as last read
    this.dirty = false; // the form holds the owner's unsaved changes
    this.port = el("input", { id: "till-port", "aria-describedby": "till-port-hint", type: "number", min: 0, max: 65535, step: 1, inputmode: "numeric", required: true });
    this.printer = el("input", { id: "till-printer", "aria-describedby": "till-printer-hint", type: "text", maxlength: 255, autocomplete: "off", spellcheck: "false", placeholder: "192.168.1.50:9100" });
    this.codePage = el("select", { id: "till-code-page", "aria-describedby": "till-code-page-hint" });
    this.saveBtn = el("button", { type: "submit", class: "primary", "data-needs-online": true, "data-i18n": "owner.till.save" });
    this.words = el("div", { class: "till-state", role: "status", "aria-live": "polite", "data-testid": "till-state" });
    const form = el(
      "form",
      { class: "till-printer", "data-i18n-aria-label": "owner.till.printerTitle" },
      field("till-port", "owner.till.port", this.port, hint("till-port-hint", "owner.till.portNote")),
      field("till-printer", "owner.till.printer", this.printer, hint("till-printer-hint", "owner.till.printerNote")),
      field("till-code-page", "owner.till.codePage", this.codePage, hint("till-code-page-hint", "owner.till.codePageNote")),
      el("div", { class: "form-buttons" }, this.saveBtn),
    );
    form.addEventListener("submit", (e) => {
      e.preventDefault();
      if (this._validPort() && form.reportValidity()) this._save();
    });
    form.addEventListener("input", () => {
      this.dirty = true;
      this.port.setCustomValidity("");
    });
    this.names = new MenuNames(conn, live);
    // A pattern saved read the waiting tickets: the names they printed are listed afresh.
    this.pattern = new PatternSetup(conn, live, (till) => {
      this.got(till);
      this.names.load();
    });
    this.section = el(
      "section",
      { class: "card rest-till", "aria-labelledby": "rest-till-title" },
      el("h2", { id: "rest-till-title", "data-i18n": "owner.till.title" }),
      el("p", { class: "muted", "data-i18n": "owner.till.note" }),
      this.words,
      el("h3", { "data-i18n": "owner.till.printerTitle" }),
      form,
      this.pattern.section,
      this.names.section,
    );
    conn.addEventListener("snapshot", (e) => {
      const snap = e.detail.data && e.detail.data[TOPIC];
      if (snap) this.got(snap);
    });
    conn.addEventListener("update", (e) => e.detail.topic === TOPIC && this.got(e.detail.data));
    this.fillCodePages();
  }

  /** The tab was opened: the till's state follows, the lists are read afresh. */
  load() {
    this.conn.subscribe([TOPIC]);
    this.pattern.load();
    this.names.load();
  }

  /** The code pages' words (again after a language change), the choice kept. */
  fillCodePages() {
    const was = this.codePage.value || (this.state && this.state.encoding) || "auto";
    // A fixed set of options drawn again in new words: one node per code page, kept.
    if (!this.codePage.options.length) {
      for (const value of Object.keys(CODE_PAGES)) this.codePage.append(el("option", { value }));
    }
    for (const option of this.codePage.options) option.textContent = t(CODE_PAGES[option.value]);
    this.codePage.value = was;
    if (this.state) this._say(this.state);
    this.pattern.relabel();
    this.names.relabel();
  }

  /** The till's state, read or saved: the words follow; the form too, unless the owner is
   *  changing it (`force`: the owner's own save). */
  got(state, { force = false } = {}) {
    if (!state) return;
    this.state = state;
    this._say(state);
    if (this.dirty && !force) return;
    this.dirty = false;
    this.port.value = String(state.port ?? 0);
    this.printer.value = state.printer || "";
    this.codePage.value = Object.hasOwn(CODE_PAGES, state.encoding) ? state.encoding : "auto";
  }

  _say(state) {
    const w = stateWords(state);
    this.words.classList.toggle("trouble", w.trouble);
    this.words.textContent = "";
    this.words.append(el("p", { class: "till-port-state" }, w.port), el("p", { class: "till-printer-state" }, w.printer), el("p", {}, w.pattern));
  }

  /** 0 (off) or a port the server may open (1024-65535). */
  _validPort() {
    const n = Number(this.port.value);
    const ok = Number.isInteger(n) && (n === 0 || (n >= 1024 && n <= 65535));
    this.port.setCustomValidity(ok ? "" : t("errors.invalid.tillPort"));
    if (!ok) this.port.reportValidity();
    return ok;
  }

  async _save() {
    const msg = {
      clientmsg: "till",
      action: "setup",
      port: Number(this.port.value),
      printer: this.printer.value.trim(),
      encoding: this.codePage.value,
    };
    const reply = await act(this.saveBtn, () => this.conn.request(msg));
    if (!reply) return;
    this.dirty = false;
    this.got(reply.till, { force: true });
    toast(t("owner.till.saved"));
  }
}
