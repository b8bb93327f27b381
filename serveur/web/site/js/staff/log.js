// The owner's the activity (audit) log, filterable.

export class LogPanel {
  constructor(root, conn, live) {
    this.root = root;
    this.conn = conn;
    this.live = live;
  }

  /** The tab was opened. */
  shown() {}
}
