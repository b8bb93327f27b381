// A zone's lease as staff see it (docs/zones.md): who holds the zone and who waits for it, in
// words, and the Release button that breaks a lease stuck on a robot pushed out of the zone by
// hand (`release`). Shown by the map's side panel (maptools.js) and by the Restaurant tab's zones
// (restaurant/zones.js); it imports neither.

import { act, confirmDialog, el, toast } from "../ui.js";
import { t } from "../i18n.js";

/** A zone's lease in words: who is in it and who waits for it. */
export function leaseWords(lease) {
  const holders = (lease && lease.holders) || [];
  const waiting = (lease && lease.waiting) || [];
  const parts = [holders.length ? t("zones.heldBy", { robots: holders.join(", ") }) : t("zones.free")];
  if (waiting.length) parts.push(t("zones.waiting", { robots: waiting.join(", ") }));
  return parts.join(" · ");
}

/** Break `robot`'s lease on `zone`, once staff confirm the robot is out of the zone. */
export async function releaseLease(conn, zone, robot, button) {
  const yes = await confirmDialog(t("zones.releaseQuestion", { zone, robot }), {
    yes: t("zones.releaseYes"),
    no: t("zones.releaseNo"),
    detail: t("zones.releaseDetail", { zone, robot }),
  });
  if (!yes) return;
  const reply = await act(button, () => conn.request({ clientmsg: "release", zone, robot }));
  if (reply) toast(t("zones.released", { zone, robot }));
}

/** The Release buttons of a zone's row: one per robot holding it. */
export function releaseButtons(conn, zone, lease) {
  return ((lease && lease.holders) || []).map((robot) =>
    el("button", {
      class: "secondary",
      "data-needs-online": true,
      "aria-label": t("zones.releaseFor", { zone, robot }),
      text: t("zones.release"),
      onclick: (e) => releaseLease(conn, zone, robot, e.currentTarget),
    }),
  );
}
