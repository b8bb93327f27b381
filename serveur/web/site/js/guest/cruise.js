// "Touch me to stop": a cruising robot's screen (issue 32) stops the robot at any touch, click
// or key, once per touch — the face (guest/robot-modes.js) says so. Between two places or
// pausing at one, the robot is stopped where it stands (`stop`); it goes on by itself after
// the site's cruise_resume, or when staff send it on.

import { showError } from "../ui.js";

/** On a cruise, going round or pausing at a place (the screen shows its face). */
export function cruising(live, robot) {
  const task = robot.current_task === null ? null : live.tasks.get(robot.current_task);
  return Boolean(task && task.kind === "cruise" && ["Delivering", "Delivered"].includes(robot.status));
}

export class TouchToStop {
  /** `request(msg)` sends `msg` for this screen's robot `name`. */
  constructor(live, name, request) {
    this.live = live;
    this.name = name;
    this.request = request;
    this.asked = ""; // the moment a stop was sent for: a touch's pointerdown and click are one
  }

  /** A touch, a click or a key on the screen. */
  touched() {
    const robot = this.live.robots.get(this.name);
    if (!robot || !cruising(this.live, robot) || document.querySelector("dialog[open]")) return;
    const moment = `${robot.current_task}:${robot.status}:${robot.status_since}`;
    if (moment === this.asked) return;
    this.asked = moment;
    this.request({ clientmsg: "stop" }).catch((err) => {
      this.asked = ""; // said so: the next touch tries again
      showError(err);
    });
  }
}
