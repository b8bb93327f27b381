// Which tray each dish is on, as the robot and table screens say it (issue 32): the tray staff
// chose for the dish (order.tray) when they chose one, else its stop's — tray k holds the
// dishes of the stop with seq k-1 (stops in visiting order). So two stops' dishes may share a
// tray, and one stop's dishes may be on two trays. Pure: records in, plain data out.

/** The tray `order` (a record, or null while not loaded) of `stop` is on. */
export function trayOf(order, stop) {
  return order && Number.isInteger(order.tray) ? order.tray : stop.seq + 1;
}

/**
 * A stop's dishes by tray, trays ascending: [{tray, orders}], each order the record `find(id)`
 * gives, or null while it is not loaded (counted on its stop's tray until it is).
 */
export function stopTrays(stop, find) {
  const trays = new Map();
  for (const id of stop.orders) {
    const order = find(id);
    const tray = trayOf(order, stop);
    if (!trays.has(tray)) trays.set(tray, []);
    trays.get(tray).push(order);
  }
  return [...trays].sort((a, b) => a[0] - b[0]).map(([tray, orders]) => ({ tray, orders }));
}

/**
 * What goes on which tray of a trip, for staff loading it at the pass, trays ascending:
 * [{tray, tables, dishes: [{order, table}]}], `tables` the tables its dishes go to in visiting
 * order. A stop whose dishes staff all put on other trays leaves its own tray out.
 */
export function tripTrays(task, find) {
  const trays = new Map();
  for (const stop of [...task.stops].sort((a, b) => a.seq - b.seq)) {
    for (const id of stop.orders) {
      const order = find(id);
      const tray = trayOf(order, stop);
      if (!trays.has(tray)) trays.set(tray, { tray, tables: [], dishes: [] });
      const entry = trays.get(tray);
      if (!entry.tables.includes(stop.table)) entry.tables.push(stop.table);
      entry.dishes.push({ order, table: stop.table });
    }
  }
  return [...trays.values()].sort((a, b) => a.tray - b.tray);
}

/** "1", "1 and 3", "1和3", "1 dan 3": trays (or tables) as the page's language lists them. */
export function listWords(items, locale = document.documentElement.lang) {
  const words = items.map(String);
  try {
    return new Intl.ListFormat(locale || undefined, { type: "conjunction" }).format(words);
  } catch {
    return words.join(", "); // a browser without Intl.ListFormat
  }
}
