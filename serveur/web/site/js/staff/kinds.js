// The kinds of places robots go to, in the order the lists show them, and their words: a table,
// a robot's home, the pass, the dish return (where a robot brings used plates to be emptied), a
// dock (a robot's charger), any other place.

import { t } from "../i18n.js";

export const PLACE_KINDS = ["table", "home", "pass", "dish_return", "dock", "other"];

// The newer kinds' keys written whole (the i18n test reads them in the source).
const NEWER = { dish_return: "wp.kind.dish_return", dock: "wp.kind.dock" };

/** "table", "dish return", "charger (dock)"... */
export function kindName(kind) {
  return t(NEWER[kind] || `wp.kind.${kind}`);
}
