// Sound on the screens guests see (the robot's own screen, a table's screen): a chime when a
// robot brings the food, and the words said aloud — "Your food is here! Please take tray 1";
// and, when it brings something special (a birthday cake), "Happy Birthday to You" instead.
//
// Offline, by design:
// - The chime is made on the device with Web Audio (three short sine tones): no audio file is
//   shipped and nothing is fetched. So is the birthday song (BIRTHDAY: the melody of "Happy
//   Birthday to You", public domain), one oscillator a note.
// - The words are said by the browser's speechSynthesis, and only with a voice that runs on the
//   device: `localService` true, for the page's language (en, zh, ms). A voice not marked local
//   (Chrome's "Google …" voices) sends the text to a server on the internet, which a
//   restaurant's Wi-Fi may not reach; it is never used. Which local voices exist depends on the
//   device: Android's text-to-speech (its own offline voices), iPadOS, Windows and macOS have
//   some; a Linux tablet has one only with speech-dispatcher and a voice installed (espeak-ng).
//   Without a local voice for the language, the chime sounds alone: the screen already shows
//   the same words in large type ("Please take tray 1"), and data-arrival-sound says "chime".
//
// Browsers keep a page silent until a person has touched it once (the autoplay policy). Until
// then the sound is "blocked" and the page shows soundPrompt's "Tap here to turn the sound on";
// any touch or key on the page turns it on. An arrival while blocked is not lost: the page
// draws again when the sound comes on (onChange) and the arrival sounds then, if the robot is
// still there. A kiosk browser started with --autoplay-policy=no-user-gesture-required never
// blocks (docs/deploy.md, "Sound on the robot and table screens").
//
// Each arrival sounds once on a device: the arrivals announced (or muted) are kept in
// localStorage, so a redraw or a reload of the page does not sound one again. Staff may mute a
// screen (muteButton); that choice is kept on the device too.
//
// What was played is on <body>, for whoever checks (the tests do): data-sound (on, blocked,
// off), data-chimes (chimes sounded), data-songs (songs started), data-spoken (sentences handed
// to speechSynthesis), data-arrival (the last arrival decided) and data-arrival-sound (what it
// did: spoken, chime, song, blocked, muted, heard). The staff console's alerts
// (js/staff/alerts.js) have a chime of their own, which could be this module's Chime.

import { el } from "./ui.js";
import { keep, kept } from "./keep.js";
import { onLangChange, t } from "./i18n.js";

/** A rising "ding-ding-ding": news for a guest (the console's alert chime falls instead). */
export const ARRIVAL_NOTES = [660, 880, 1320];
const NOTE_S = 0.22;
const SPEAK_AFTER_MS = 800; // the words come once the chime has rung
const HEARD_KEPT = 50; // arrivals remembered per screen: far more than stand at a table at once
const CLICK_WAIT_MS = 500; // a touch's click comes well within this (soundPrompt)

/**
 * "Happy Birthday to You" (Mildred and Patty Hill, 1893; the melody is in the public domain),
 * in C major, 3/4: [MIDI note, beats]. Its four lines, the third reaching up to the octave.
 */
export const BIRTHDAY = [
  [67, 0.75], [67, 0.25], [69, 1], [67, 1], [72, 1], [71, 2],
  [67, 0.75], [67, 0.25], [69, 1], [67, 1], [74, 1], [72, 2],
  [67, 0.75], [67, 0.25], [79, 1], [76, 1], [72, 1], [71, 1], [69, 2],
  [77, 0.75], [77, 0.25], [76, 1], [72, 1], [74, 1], [72, 2],
];
const BEAT_S = 0.42; // a beat of the song: about 140 a minute, as it is sung at a table

/** A MIDI note's pitch (69 is the A at 440 Hz). */
export function pitch(note) {
  return 440 * 2 ** ((note - 69) / 12);
}

/**
 * Short tones made with Web Audio. The AudioContext is made at once: a browser that blocks
 * sound makes it "suspended", which is how the page knows to ask for a touch (`blocked`).
 */
export class Chime {
  constructor(notes = ARRIVAL_NOTES) {
    this.notes = notes;
    this.ctx = null;
    this.song = []; // the oscillators of a song still playing, for hush()
    try {
      if (typeof AudioContext !== "undefined") this.ctx = new AudioContext();
    } catch {
      this.ctx = null; // no Web Audio: no chime, the words may still be said
    }
  }

  /** Sound is held back until a person touches the page. */
  get blocked() {
    if (this.ctx) return this.ctx.state !== "running" && this.ctx.state !== "closed";
    return navigator.userActivation ? !navigator.userActivation.hasBeenActive : false;
  }

  /** Called from a touch or a key: the browser lets the context run from here on. */
  unlock() {
    if (!this.ctx || this.ctx.state === "running") return Promise.resolve();
    return this.ctx.resume().catch(() => {});
  }

  /** Ring once; false if the browser holds the sound back (nothing was heard). */
  play() {
    if (!this.ctx || this.ctx.state !== "running") return false;
    const ctx = this.ctx;
    const start = ctx.currentTime + 0.02;
    this.notes.forEach((freq, i) => {
      const osc = ctx.createOscillator();
      const gain = ctx.createGain();
      const at = start + i * NOTE_S;
      osc.type = "sine";
      osc.frequency.value = freq;
      gain.gain.setValueAtTime(0.0001, at);
      gain.gain.exponentialRampToValueAtTime(0.5, at + 0.02);
      gain.gain.exponentialRampToValueAtTime(0.0001, at + NOTE_S * 1.6);
      osc.connect(gain).connect(ctx.destination);
      osc.start(at);
      osc.stop(at + NOTE_S * 1.7);
    });
    return true;
  }

  /**
   * Play a tune ([MIDI note, beats], BIRTHDAY) once; false if the browser holds the sound
   * back. A triangle wave, each note slightly detached so repeated notes are heard as two.
   */
  melody(tune, beat = BEAT_S) {
    if (!this.ctx || this.ctx.state !== "running") return false;
    this.hush();
    const ctx = this.ctx;
    let at = ctx.currentTime + 0.05;
    for (const [note, beats] of tune) {
      const length = beats * beat;
      const osc = ctx.createOscillator();
      const gain = ctx.createGain();
      osc.type = "triangle";
      osc.frequency.value = pitch(note);
      gain.gain.setValueAtTime(0.0001, at);
      gain.gain.exponentialRampToValueAtTime(0.45, at + 0.03);
      gain.gain.setValueAtTime(0.45, at + length * 0.7);
      gain.gain.exponentialRampToValueAtTime(0.0001, at + length * 0.95);
      osc.connect(gain).connect(ctx.destination);
      osc.start(at);
      osc.stop(at + length);
      this.song.push(osc);
      at += length;
    }
    return true;
  }

  /** Stop a song still playing (its robot has moved on). */
  hush() {
    for (const osc of this.song) {
      try {
        osc.stop();
      } catch {
        /* already stopped */
      }
    }
    this.song = [];
  }
}

// The first part of a voice's language tag each page language accepts, and the region preferred
// when the device has several (the pages' Chinese is Simplified, their Malay Malaysia's).
const VOICE_LANGS = { en: ["en"], zh: ["zh", "cmn"], ms: ["ms", "zsm"] };
const PREFERRED = { en: /^en/i, zh: /^(zh|cmn)[-_](cn|sg|hans)/i, ms: /^ms[-_]my/i };

/** A voice on this device (never a network one) that speaks `lang`, or null. */
export function localVoice(lang) {
  const synth = window.speechSynthesis;
  if (!synth || typeof synth.getVoices !== "function") return null;
  const bases = VOICE_LANGS[lang] || [lang];
  const fits = synth
    .getVoices()
    .filter((v) => v.localService && bases.includes(String(v.lang).toLowerCase().split(/[-_]/)[0]));
  return fits.find((v) => v.default) || fits.find((v) => PREFERRED[lang]?.test(v.lang)) || fits[0] || null;
}

/** Say `text` with `voice` (a local one), replacing anything still being said. */
function say(text, voice) {
  const synth = window.speechSynthesis;
  const words = new SpeechSynthesisUtterance(text);
  words.voice = voice;
  words.lang = voice.lang;
  words.rate = 0.95;
  synth.cancel();
  synth.speak(words);
}

/**
 * One screen's arrival sound: the chime and the words, once per arrival, unless muted or held
 * back. `page` names the screen's kind ("robot", "table") for what the device keeps.
 */
export class Announcer {
  constructor(page) {
    this.keys = { muted: `serveur.sound.muted.${page}`, heard: `serveur.sound.heard.${page}` };
    this.muted = kept(this.keys.muted) === 1; // "1" or "0": storage disabled, until a reload
    this.heard = this._loadHeard();
    this.chime = new Chime();
    this.listeners = [];
    this.chimes = 0;
    this.songs = 0;
    this.spoken = 0;
    this.state = this._state();
    const wake = () => {
      this.chime.unlock().then(() => this._update());
      this._update(); // no Web Audio: the touch alone lets speech through
    };
    window.addEventListener("pointerdown", wake, { capture: true });
    window.addEventListener("keydown", wake, { capture: true });
    if (this.chime.ctx) this.chime.ctx.addEventListener("statechange", () => this._update());
    // Voices often arrive after the page has loaded: an arrival held back for them sounds then.
    window.speechSynthesis?.addEventListener?.("voiceschanged", () => this._notify());
    this._show();
  }

  /** Call `f(state)` when the sound turns on, off or is held back. */
  onChange(f) {
    this.listeners.push(f);
  }

  setMuted(muted) {
    this.muted = muted;
    keep(this.keys.muted, muted ? 1 : 0);
    if (muted) {
      window.speechSynthesis?.cancel();
      this.chime.hush();
    }
    this._update(true);
  }

  /**
   * A robot stands at a table with food: ring and say `text` in `lang`, once per `key` (the
   * robot, the trip and its stop) on this device. Returns what happened (data-arrival-sound).
   */
  announce(key, text, lang) {
    const outcome = this._announce(key, text, lang);
    // A redraw's "heard" does not hide what this page did for the arrival it already decided.
    if (outcome !== "heard" || document.body.dataset.arrival !== key) {
      document.body.dataset.arrival = key;
      document.body.dataset.arrivalSound = outcome;
    }
    return outcome;
  }

  /**
   * A robot stands at a table with something special: play the birthday song (in place of the
   * chime and the words), once per `key` on this device, as announce() does.
   */
  sing(key) {
    return this.announce(key, null, null);
  }

  /** A person asked for the song again: play it now, unless the screen is muted. */
  singAgain() {
    if (this.muted) return Promise.resolve(false);
    return this.chime.unlock().then(() => this._song());
  }

  /** Stop the song (its robot has moved on). */
  hush() {
    this.chime.hush();
  }

  _song() {
    if (!this.chime.melody(BIRTHDAY)) return false;
    this.songs += 1;
    document.body.dataset.songs = String(this.songs);
    return true;
  }

  _announce(key, text, lang) {
    if (this.heard.includes(key)) return "heard";
    if (this.muted) {
      this._remember(key);
      return "muted";
    }
    if (text === null) {
      // The song: Web Audio or nothing (there are no words to say in its place).
      if (this.chime.ctx && !this._song()) return "blocked"; // sounds on unlock
      this._remember(key);
      return this.chime.ctx ? "song" : "none";
    }
    if (this.chime.ctx ? !this.chime.play() : this.chime.blocked) return "blocked"; // sounds on unlock
    this._remember(key);
    if (this.chime.ctx) {
      this.chimes += 1;
      document.body.dataset.chimes = String(this.chimes);
    }
    const voice = localVoice(lang);
    if (!voice) return "chime";
    setTimeout(() => {
      if (this.muted) return;
      say(text, voice);
      this.spoken += 1;
      document.body.dataset.spoken = String(this.spoken);
    }, SPEAK_AFTER_MS);
    return "spoken";
  }

  _loadHeard() {
    const list = kept(this.keys.heard, []);
    return Array.isArray(list) ? list.map(String) : [];
  }

  _remember(key) {
    this.heard = [...this.heard.filter((k) => k !== key), key].slice(-HEARD_KEPT);
    keep(this.keys.heard, this.heard);
  }

  _state() {
    if (this.muted) return "off";
    return this.chime.blocked ? "blocked" : "on";
  }

  _update(force = false) {
    const state = this._state();
    if (state === this.state && !force) return;
    this.state = state;
    this._show();
    this._notify();
  }

  _show() {
    document.body.dataset.sound = this.state;
  }

  _notify() {
    for (const f of this.listeners) f(this.state);
  }
}

/**
 * "Tap here to turn the sound on": shown while the browser holds the sound back (and the screen
 * is not muted); pressing it (or touching anything on the page) turns the sound on.
 */
export function soundPrompt(announcer) {
  const button = el("button", { type: "button", class: "sound-prompt", "data-i18n": "guest.sound.turnOn" });
  // The page-wide listener does the unlocking; the button is what a guest sees to press.
  button.addEventListener("click", () => announcer.chime.unlock());
  // The first touch turns the sound on wherever it lands — on "Food collected", say. Hidden
  // during that touch, the prompt would move the page up under the finger and the button would
  // miss its click: it goes once the click this touch makes is over. A finger's click comes a
  // moment after the touch ends (the sound may have come on in between); a touch that makes
  // none (a scroll) lets it go after CLICK_WAIT_MS.
  let touching = false;
  let settle = null;
  const show = () => {
    if (!touching) button.hidden = announcer.state !== "blocked";
  };
  const settled = () => {
    clearTimeout(settle);
    window.removeEventListener("click", settled, true);
    touching = false;
    setTimeout(show, 0); // after the click's own handlers
  };
  window.addEventListener("pointerdown", () => (touching = true), { capture: true });
  const ended = () => {
    clearTimeout(settle);
    window.addEventListener("click", settled, { capture: true, once: true });
    settle = setTimeout(settled, CLICK_WAIT_MS);
  };
  window.addEventListener("pointerup", ended, { capture: true });
  window.addEventListener("pointercancel", ended, { capture: true });
  announcer.onChange(show);
  show();
  return button;
}

/** The screen's mute, for staff: its words say the state ("Sound on"), its hint what a press does. */
export function muteButton(announcer, attrs = {}) {
  const button = el("button", { type: "button", class: "sound-mute secondary small", ...attrs });
  const show = () => {
    button.dataset.muted = String(announcer.muted);
    button.textContent = announcer.muted ? t("guest.sound.off") : t("guest.sound.on");
    button.title = announcer.muted ? t("guest.sound.unmuteHint") : t("guest.sound.muteHint");
  };
  button.addEventListener("click", () => announcer.setMuted(!announcer.muted));
  announcer.onChange(show);
  onLangChange(show);
  show();
  return button;
}
