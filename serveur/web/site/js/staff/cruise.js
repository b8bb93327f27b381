// Cruising (a free robot going round places again and again: snacks, a tasting, an advert on
// its screen): "Cruise…" picks the places in the order the robot visits them and sends
// `cruise`; "Back to deliveries" ends a cruise the way the protocol does — `stop` (from a stop,
// `next` first: a robot paused at a place cannot be stopped), then `cancel`, and the robot goes
// home into service. Each step is taken from the robot's status as this page sees it; a step
// refused because the robot moved on meanwhile (`stale`, `not_allowed_in_status`) is taken again
// from its new status, and a refusal that remains is shown in words (errors.js).

import { act, byName, el, toast } from "../ui.js";
import { t } from "../i18n.js";
import { field, formDialog } from "./forms.js";
import { cruising } from "./trips.js";

// The places a cruise may visit: not a robot's home or charger.
const NOT_VISITED = new Set(["home", "dock"]);
// What ends a cruise from each status (then the next step from the status it comes to).
const STEP = { Delivered: "next", Delivering: "stop", Transit: "stop", Stopped: "cancel", Error: "cancel" };
const STEP_WAIT_MS = 8000; // the robot's new status comes within a second or two

/** Resolves true once `cond()` holds on the live state, false after `ms`. */
export function whenLive(live, cond, ms) {
  return new Promise((resolve) => {
    if (cond()) {
      resolve(true);
      return;
    }
    const check = () => {
      if (!cond()) return;
      finish(true);
    };
    const timer = setTimeout(() => finish(false), ms);
    function finish(ok) {
      clearTimeout(timer);
      live.removeEventListener("change", check);
      resolve(ok);
    }
    live.addEventListener("change", check);
  });
}

/** A local refusal, already in the page's words (ui.js describeError shows its message). */
function refusal(message) {
  const err = new Error(message);
  err.local = true;
  return err;
}

/** "Cruise…": pick the places in order, then `cruise`. */
export async function pickCruise(conn, live, name) {
  const places = [...live.waypoints.values()].filter((w) => !NOT_VISITED.has(w.kind)).map((w) => w.name).sort(byName);
  const route = [];
  const shown = el("output", { id: "cr-route", class: "cruise-route", "aria-live": "polite" });
  const buttons = new Map();
  const show = () => {
    shown.textContent = route.length ? route.join(" → ") : t("cruise.noneYet");
    for (const [place, b] of buttons) {
      const at = route.indexOf(place);
      b.setAttribute("aria-pressed", String(at >= 0));
      b.textContent = at >= 0 ? t("cruise.placeNumbered", { n: at + 1, place }) : place;
    }
  };
  for (const place of places) {
    buttons.set(
      place,
      el("button", {
        type: "button",
        class: "table-btn",
        "data-place": place,
        onclick: () => {
          // Tapped again: out of the round (the others keep their order).
          const at = route.indexOf(place);
          if (at >= 0) route.splice(at, 1);
          else route.push(place);
          show();
        },
      }),
    );
  }
  const clear = el("button", {
    type: "button",
    class: "secondary",
    text: t("cruise.clear"),
    onclick: () => {
      route.length = 0;
      show();
    },
  });
  show();
  await formDialog({
    title: t("cruise.title", { name }),
    yes: t("cruise.start"),
    fields: [
      el("p", { class: "muted rest-hint", text: t("cruise.note") }),
      el("div", { class: "cruise-places table-grid", role: "group", "aria-label": t("cruise.places") }, ...buttons.values()),
      field("cr-route", "cruise.route", shown),
      el("div", { class: "form-buttons" }, clear),
    ],
    submit: async () => {
      if (!route.length) throw refusal(t("cruise.pickFirst"));
      await conn.request({ clientmsg: "cruise", robot: name, route: [...route] });
      toast(t("cruise.started", { name, route: route.join(" → ") }));
      return true;
    },
  });
}

/** "Back to deliveries": the cruise ends, the robot goes home into service. */
export async function endCruise(conn, live, button, name) {
  const done = await act(button, async () => {
    let refused = null;
    for (let tries = 0; tries < 6; tries += 1) {
      const robot = live.robots.get(name);
      if (!robot || !cruising(live, robot)) return true; // ended (here, elsewhere, or by itself)
      const verb = STEP[robot.status];
      if (!verb) throw refused || refusal(t("cruise.cannotEnd", { name }));
      const seen = `${robot.status}/${robot.current_task}/${live.tasks.get(robot.current_task)?.current_stop}`;
      try {
        await conn.request({ clientmsg: verb, robot: name, ...live.target(name) });
        refused = null;
      } catch (err) {
        // It moved on meanwhile: the next step is taken from where it is now.
        if (err.code !== "stale" && err.code !== "not_allowed_in_status") throw err;
        refused = err;
      }
      const moved = () => {
        const r = live.robots.get(name);
        return !r || `${r.status}/${r.current_task}/${live.tasks.get(r.current_task)?.current_stop}` !== seen;
      };
      if (!(await whenLive(live, moved, STEP_WAIT_MS)) && refused) throw refused;
    }
    throw refused || refusal(t("cruise.cannotEnd", { name }));
  });
  if (done) toast(t("cruise.ended", { name }));
}
