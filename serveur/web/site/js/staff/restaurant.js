// The owner's robots (edit, remove, the link's last error), tables and places (rename, move, remove), site settings.

export class RestaurantPanel {
  constructor(root, conn, live) {
    this.root = root;
    this.conn = conn;
    this.live = live;
  }

  /** The tab was opened. */
  shown() {}
}
