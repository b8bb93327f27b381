// What went wrong with a robot or a table, in a waiter's words. The server keeps its driver's
// own text (`last_error`, a block's `reason`: "move_base ABORTED: no path to the goal...") for
// whoever integrates the robots; staff read what happened and what to do, from the robot's
// status and where it was going, and the driver's text sits folded under "For the technician".

import { el } from "../ui.js";
import { t } from "../i18n.js";

/** The robot's trouble as one sentence for staff, or null when there is none to tell. */
export function troubleWords(robot, live) {
  if (robot.status === "Error") {
    const place = live.destination(robot.name);
    return place ? t("trouble.stuckGoing", { place }) : t("trouble.stuck");
  }
  if (robot.status === "Manual" && robot.last_error) return t("trouble.spotFailed");
  return null;
}

/** Why a table is blocked, as staff read it: which robot could not get there. */
export function blockWords(block) {
  return block.robot ? t("trouble.blockedBy", { robot: block.robot }) : t("trouble.blocked");
}

/** The driver's own text, folded away: shown only when someone opens it. */
export function technicalNote(text) {
  if (!text) return null;
  return el(
    "details",
    { class: "tech-note" },
    el("summary", { "data-i18n": "trouble.technical" }),
    el("span", { class: "tech-text", lang: "en" }, text),
  );
}
