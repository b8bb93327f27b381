// The robot screen for what a robot does besides delivering dishes (issue 32), by its trip's
// kind and its current stop's purpose, in a guest's and a waiter's words: the server's robot
// is "Delivering" between any two stops and "Delivered" at any stop, which this screen never
// says of a bussing or cruising robot.
//
// - Bussing: on its way, "Coming to take the plates at T3"; at a table (collect), "Please put
//   your used plates on my trays" and a big Done; at the dish return (unload), "Please empty
//   my trays" (for staff) and Done; back, "Taking the used plates back".
// - A special delivery (a dish of the stop has a message, a birthday): the message large, the
//   dishes and their tray, Done and "Play the song again" (the song itself: sound.js).
// - Cruise: going round or pausing at a place, the whole screen is a smiling face saying
//   "Help yourself" — any touch or key stops the robot (guest/cruise.js); stopped, "I'll go on
//   in a moment", and going on sooner or ending the cruise are staff's, once signed in.
// - Charging: "Charging — 45 %", and nothing to press.
//
// modeView(m, acts) draws these from the robot screen's model `m` (robot.js `model`), or
// returns null for a screen robot.js draws itself; `acts` are robot.js's requests.

import { el } from "../ui.js";
import { t } from "../i18n.js";
import { bigButton, smallButton, staffControls, takeTray, yourDishes } from "./widgets.js";

/** The nodes of the screen for `m`, or null when it is a delivery's (or idle) screen. */
export function modeView(m, acts) {
  if (m.face) return cruiseFace(acts);
  if (m.status === "Charging") return charging(m);
  if (m.kind === "cruise") return cruise(m, acts);
  if (m.kind === "bussing") return bussing(m, acts);
  if (m.status === "Delivered" && m.special.length) return special(m, acts);
  return null;
}

function charging(m) {
  const words = m.battery === null ? t("status.Charging") : t("guest.robot.charging", { percent: m.battery });
  return [
    el("h1", {}, words),
    m.battery === null
      ? null
      : el("div", { class: "battery", "aria-hidden": "true" }, el("span", { style: { width: `${m.battery}%` } })),
    el("p", { class: "sub" }, t("guest.robot.chargingSub")),
  ];
}

/** A smiling face of plain shapes (no picture is fetched). */
function face() {
  return el(
    "span",
    { class: "face", "aria-hidden": "true" },
    el("span", { class: "eye left" }),
    el("span", { class: "eye right" }),
    el("span", { class: "smile" }),
  );
}

/** Going round or pausing at a place (m.face): the whole screen is one button; any touch or
 *  key anywhere stops the robot too (robot.js listens). */
function cruiseFace(acts) {
  return [
    el(
      "button",
      { type: "button", class: "cruise-face", onclick: () => acts.stopCruise() },
      face(),
      el("span", { class: "cruise-title" }, t("guest.robot.helpYourself")),
      el("span", { class: "cruise-hint" }, t("guest.robot.touchToStop")),
    ),
  ];
}

function cruise(m, acts) {
  if (m.status === "Stopped") {
    return [
      el("h1", {}, t("guest.robot.goOnSoon")),
      el("p", { class: "sub" }, t("guest.robot.helpYourself")),
      // Going on now, or home: staff's, so only once staff signed in on this screen.
      m.staff
        ? staffControls(
            smallButton(t("guest.robot.goOnNow"), (b) => acts.send(b, "continue")),
            smallButton(t("guest.robot.endCruise"), (b) => acts.cancel(b, CRUISE_CANCEL)),
          )
        : null,
    ];
  }
  return null; // Error, Transit: as on any trip
}

const CRUISE_CANCEL = {
  question: "guest.robot.endCruiseQuestion",
  yes: "guest.robot.endCruiseYes",
  no: "guest.robot.endCruiseNo",
  detail: "guest.robot.endCruiseDetail",
};
const BUSSING_CANCEL = {
  question: "guest.robot.endBussingQuestion",
  yes: "guest.robot.endBussingYes",
  no: "guest.robot.endBussingNo",
  detail: "guest.robot.endBussingDetail",
};

function bussing(m, acts) {
  const unload = m.purpose === "unload";
  const stop = bigButton(t("robot.stop"), (b) => acts.send(b, "stop"), "danger");
  const where = unload ? t("guest.robot.platesBack") : t("guest.robot.platesTo", { table: m.dest ?? "" });
  switch (m.status) {
    case "Delivering":
      return [el("h1", {}, where), stop];
    case "Delivered":
      // Its trip already on the next stop while its own update is on the way: not there yet.
      if (!m.arrived) return [el("h1", {}, where)];
      return unload
        ? [
            el("p", { class: "sub" }, t("guest.robot.forStaff")),
            el("h1", {}, t("guest.robot.emptyTrays")),
            bigButton(t("guest.robot.done"), (b) => acts.send(b, "next")),
            el("p", { class: "sub" }, t("guest.robot.emptyHint")),
          ]
        : [
            el("p", { class: "sub" }, t("guest.robot.platesHere")),
            el("h1", {}, t("guest.robot.putPlates")),
            bigButton(t("guest.robot.done"), (b) => acts.send(b, "next")),
            el("p", { class: "sub" }, t("guest.robot.putPlatesHint")),
          ];
    case "Stopped":
      return [
        el("h1", {}, t("robot.stopped")),
        el("p", { class: "sub" }, where),
        el(
          "div",
          { class: "choices" },
          bigButton(t("robot.continue"), (b) => acts.send(b, "continue")),
          bigButton(t("robot.cancel"), (b) => acts.cancel(b, BUSSING_CANCEL), "danger"),
        ),
      ];
    default:
      return null; // Error, Transit: as on any trip
  }
}

function special(m, acts) {
  return [
    el("p", { class: "sub" }, m.dest ? t("guest.robot.specialFor", { table: m.dest }) : t("robot.arrived")),
    el("h1", { class: "special-message" }, ...m.special.flatMap((text, i) => (i ? [el("br"), text] : [text]))),
    takeTray(m.take),
    yourDishes(m),
    el(
      "div",
      { class: "choices" },
      bigButton(t("guest.robot.done"), (b) => acts.send(b, "next")),
      m.sound ? bigButton(t("guest.robot.songAgain"), (b) => acts.singAgain(b), "secondary") : null,
    ),
    staffControls(smallButton(t("guest.robot.skip"), (b) => acts.skip(b))),
  ];
}
