// The owner's statistics, trip history, CSV export and how many robots a day needed.

export class StatsPanel {
  constructor(root, conn, live) {
    this.root = root;
    this.conn = conn;
    this.live = live;
  }

  /** The tab was opened. */
  shown() {}
}
