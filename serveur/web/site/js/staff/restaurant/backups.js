// The Restaurant tab's backups: the copies the box keeps (every night, and each one made here),
// each with its check; "Back up now" makes one and downloads it (a copy off the box, for a lost
// or broken box); any listed copy downloads or restores; a copy from elsewhere restores from its
// file. A restore is asked twice: first the server reads the copy and says what it holds and
// what would be lost, the owner confirms, then the server keeps the current state as a copy of
// its own and restarts on the restored one — this page, like every screen, reconnects.
//
// Downloads are plain links the server made (a ticket good once, for a minute): the browser
// saves the file itself, the session's token never goes in an address.

import { act, confirmDialog, describeError, el, formatTime, toast } from "../../ui.js";
import { t } from "../../i18n.js";
import { field } from "../forms.js";
import { listSection, rowButton } from "./form.js";
import { saveAs, sendFile } from "./upload.js";

const KINDS = {
  nightly: "owner.backups.kind.nightly",
  now: "owner.backups.kind.now",
  before_restore: "owner.backups.kind.beforeRestore",
};
const REASONS = {
  not_a_backup: "owner.backups.reason.notABackup",
  newer: "owner.backups.reason.newer",
  damaged: "owner.backups.reason.damaged",
  not_found: "owner.backups.reason.notFound",
  busy: "owner.backups.reason.busy",
  off: "owner.backups.reason.off",
};

function day(epoch) {
  const locale = document.documentElement.lang || undefined;
  return new Date(epoch * 1000).toLocaleDateString(locale, { weekday: "short", day: "numeric", month: "short" });
}

function megabytes(size) {
  return (size / 1e6).toFixed(size < 1e7 ? 1 : 0);
}


export class BackupsSection {
  constructor(conn) {
    this.conn = conn;
    this.restoredTo = null;
    this.nowBtn = el("button", { type: "button", class: "primary", "data-needs-online": true, "data-i18n": "owner.backups.now" });
    this.nowBtn.addEventListener("click", () => this._backupNow());
    this.fileInput = el("input", { id: "backup-file", type: "file", accept: ".db,.sqlite,application/vnd.sqlite3", required: true });
    this.status = el("p", { class: "rest-map-progress", role: "status", "aria-live": "polite" });
    const fromFile = el(
      "form",
      { class: "rest-map", "data-i18n-aria-label": "owner.backups.fromFile" },
      field("backup-file", "owner.backups.file", this.fileInput),
      el("div", { class: "form-buttons" }, el("button", { type: "submit", class: "secondary", "data-needs-online": true, "data-i18n": "owner.backups.restoreFile" })),
    );
    fromFile.addEventListener("submit", (e) => {
      e.preventDefault();
      if (fromFile.reportValidity()) this._restoreFile(e.submitter);
    });
    ({ rows: this.rows, section: this.section } = listSection(
      {
        titleId: "rest-backups-title",
        title: "owner.backups.title",
        note: "owner.backups.note",
        none: "owner.backups.none",
        signature: (b) => [b.kind, b.check, b.size],
        build: (b) => this._row(b),
      },
      el("div", { class: "form-buttons" }, this.nowBtn),
      this.status,
      fromFile,
    ));
  }

  /** The tab was opened (or a backup made): the list as the box has it now. */
  async load() {
    if (this.restoredTo) {
      this._say("owner.backups.restored", { when: this.restoredTo });
      this.restoredTo = null;
    }
    try {
      this.rows.update((await this.conn.request({ clientmsg: "site", action: "backups" })).backups);
    } catch (err) {
      if (err && err.code !== "forbidden") this._refused(err);
    }
  }

  _row(b) {
    const when = t("owner.backups.when", { day: day(b.made), time: formatTime(b.made) });
    const ok = b.check === "ok";
    return el(
      "li",
      { "data-backup": b.name, class: "rest-place" },
      el("span", { class: "rest-name", text: when }),
      el("span", { class: "rest-kind", text: t(KINDS[b.kind]) }),
      el("span", { class: ok ? "muted" : "problem", text: `${t("owner.backups.size", { mb: megabytes(b.size) })} · ${t(ok ? "owner.backups.checked" : b.check === "unchecked" ? "owner.backups.unchecked" : "owner.backups.damaged")}` }),
      el(
        "div",
        { class: "row-actions" },
        rowButton(t("owner.backups.download"), t("owner.backups.downloadFor", { when }), (e) => this._download(b.name, e.currentTarget)),
        rowButton(t("owner.backups.restore"), t("owner.backups.restoreFor", { when }), (e) => this._restore({ name: b.name }, e.currentTarget), { danger: true }),
      ),
    );
  }

  _say(key, params) {
    this.status.textContent = key ? t(key, params) : "";
  }

  _refused(err) {
    const reason = err.details && err.details.reason;
    this._say("owner.backups.refused", { why: reason && REASONS[reason] ? t(REASONS[reason]) : describeError(err) });
  }

  async _backupNow() {
    this._say("owner.backups.making");
    const reply = await act(this.nowBtn, () => this.conn.request({ clientmsg: "site", action: "backup_now" }));
    if (!reply) return this._say(null);
    this._say(reply.backup.check === "ok" ? "owner.backups.made" : "owner.backups.madeDamaged");
    saveAs(reply.download); // the server answers it as an attachment
    await this.load();
  }

  async _download(name, button) {
    const reply = await act(button, () => this.conn.request({ clientmsg: "site", action: "download_backup", name }));
    if (reply) saveAs(reply.download);
  }

  async _restoreFile(button) {
    const file = this.fileInput.files[0];
    if (!file) return;
    button.disabled = true;
    try {
      const upload = await sendFile(this.conn, file, "backup", (percent) => this._say("owner.backups.sending", { percent }));
      await this._restore({ upload }, button);
    } catch (err) {
      this._refused(err);
    } finally {
      button.disabled = false;
    }
  }

  /** Ask the server what `source` ({name} or {upload}) holds, ask the owner, then restore. */
  async _restore(source, button) {
    this._say("owner.backups.reading");
    let preview;
    try {
      preview = (await this.conn.request({ clientmsg: "site", action: "restore", ...source })).restore;
    } catch (err) {
      return this._refused(err);
    }
    this._say(null);
    const back = preview.last_activity ? t("owner.backups.when", { day: day(preview.last_activity), time: formatTime(preview.last_activity) }) : t("owner.backups.empty");
    const detail = [
      t("owner.backups.holds", { orders: preview.orders, trips: preview.trips, places: preview.places, robots: preview.robots, people: preview.people }),
      t("owner.backups.lost", { orders: preview.lost.orders, trips: preview.lost.trips }),
      t("owner.backups.after"),
    ].join(" ");
    const yes = await confirmDialog(t("owner.backups.question", { when: back }), { detail, yes: t("owner.backups.restore"), no: t("owner.cancel") });
    if (!yes) return;
    const reply = await act(button, () => this.conn.request({ clientmsg: "site", action: "restore", confirm: true, ...source }));
    if (reply) {
      this.restoredTo = back; // said when the panel is shown again, on the restored server
      this._say("owner.backups.restarting");
      toast(t("owner.backups.restarting"));
    }
  }
}
