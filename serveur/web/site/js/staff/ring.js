// The console's sound: one choice on this device (the header's "Sound on / Sound off", kept by
// keep.js) for every chime the console makes — a critical alert's (alerts.js) and a guest's new
// call (calls.js). The tones are sound.js's Chime (Web Audio, no audio file). Browsers keep a
// page silent until a person has touched it: each touch or key lets the chimes run.

import { Chime } from "../sound.js";
import { keep, kept } from "../keep.js";

const MUTE_KEY = "serveur.alertsMuted"; // the alerts' own key, from before calls rang too

class ConsoleSound {
  constructor() {
    // Kept as "1" or "0" (keep.js writes 1 as "1"); storage disabled: until the page is reloaded.
    this.muted = kept(MUTE_KEY) === 1;
    this.chimes = [];
    this.listeners = [];
    const wake = () => this.chimes.forEach((c) => c.unlock());
    window.addEventListener("pointerdown", wake, { capture: true });
    window.addEventListener("keydown", wake, { capture: true });
  }

  /** A chime of `notes` that runs once the page was touched. */
  chime(notes) {
    const chime = new Chime(notes);
    this.chimes.push(chime);
    return chime;
  }

  setMuted(muted) {
    this.muted = muted;
    keep(MUTE_KEY, muted ? 1 : 0);
    this.listeners.forEach((f) => f(muted));
  }

  /** `f(muted)` when the choice changes. */
  onChange(f) {
    this.listeners.push(f);
  }
}

/** The console's one sound choice. */
export const consoleSound = new ConsoleSound();
