// Keyboard: the original program's keys, plus a few of ours.
import type { App } from './app';
import { toggleHelp } from './ui';

/** Key, what it does (shown in the help overlay and in docs/viewer.md). */
export const KEYS: [string, string][] = [
  ['v', 'lit surface ↔ wireframe'],
  ['s / h / b', 'structural / shear / bend springs on or off (wireframe)'],
  ['p', 'pause or resume'],
  ['n', 'single step (pauses)'],
  ['space', 'start or stop frame capture (zip of PNGs)'],
  ['z / x', 'zoom in / out (also the wheel)'],
  ['e', 'reset the camera'],
  ['f', 'force-field arrows on or off'],
  ['r', 'reset to the loaded world'],
  ['?', 'this help'],
];

export function bindKeys(app: App): void {
  window.addEventListener('keydown', (e) => {
    // Leave typing in the panel's fields alone.
    const t = e.target as HTMLElement | null;
    if (t && (t.tagName === 'INPUT' || t.tagName === 'SELECT' || t.tagName === 'TEXTAREA')) return;
    if (e.ctrlKey || e.metaKey || e.altKey) return;
    let handled = true;
    switch (e.key) {
      case 'v':
        app.mode = app.mode === 'lit' ? 'wireframe' : 'lit';
        break;
      case 's':
      case 'h':
      case 'b': {
        const kind = 'shb'.indexOf(e.key);
        app.showKind[kind] = !app.showKind[kind];
        break;
      }
      case 'p':
        app.paused = !app.paused;
        break;
      case 'n':
        app.stepOnce();
        break;
      case ' ':
        app.toggleSequence();
        break;
      case 'z':
        app.viewer.zoom(0.9);
        break;
      case 'x':
        app.viewer.zoom(1 / 0.9);
        break;
      case 'e':
        app.resetCamera();
        break;
      case 'f':
        if (app.hasField) app.showField = !app.showField;
        break;
      case 'r':
        app.reset();
        break;
      case '?':
        toggleHelp();
        break;
      case 'Escape':
        toggleHelp(false);
        break;
      default:
        handled = false;
    }
    if (handled) {
      e.preventDefault(); // space must not scroll or press a focused button
      app.panel.refresh();
    }
  });
}
