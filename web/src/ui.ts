// Page chrome outside the 3-D view: banners (errors, blow-ups, recording), the readout of frame
// rate and stepping speed, the help overlay, and drag-and-drop of world files.

/** `integrator`: the viewer chose the integrator of a large scene (see `startingParameters`). */
export type BannerKind = 'error' | 'blowup' | 'info' | 'integrator';

export interface BannerAction {
  label: string;
  run: () => void;
}

/** Shows one banner per kind; a new message of a kind replaces the old one. */
export class Banners {
  private readonly shown = new Map<BannerKind, HTMLElement>();

  constructor(private readonly host: HTMLElement) {}

  show(kind: BannerKind, message: string, actions: BannerAction[] = []): void {
    this.clear(kind);
    const el = document.createElement('div');
    el.className = `banner banner-${kind}`;
    el.dataset.kind = kind;
    el.setAttribute('role', kind === 'info' || kind === 'integrator' ? 'status' : 'alert');
    const text = document.createElement('span');
    text.className = 'banner-text';
    text.textContent = message;
    el.append(text);
    for (const a of actions) {
      const b = document.createElement('button');
      b.textContent = a.label;
      b.addEventListener('click', a.run);
      el.append(b);
    }
    const close = document.createElement('button');
    close.className = 'banner-close';
    close.textContent = '×';
    close.title = 'Dismiss';
    close.addEventListener('click', () => this.clear(kind));
    el.append(close);
    this.host.append(el);
    this.shown.set(kind, el);
  }

  clear(kind: BannerKind): void {
    this.shown.get(kind)?.remove();
    this.shown.delete(kind);
  }
}

/** Frame rate and stepping speed, averaged over about half a second. */
export class Readout {
  fps = 0;
  stepsPerSecond = 0;
  /** Simulated seconds per wall second actually achieved. */
  realTimeFactor = 0;
  private frames = 0;
  private steps = 0;
  private simulated = 0;
  private since = performance.now();

  constructor(private readonly el: HTMLElement) {}

  /** Counts a frame; refreshes the text every half second. */
  frame(steps: number, dt: number, status: () => string): void {
    this.frames++;
    this.steps += steps;
    this.simulated += steps * dt;
    const now = performance.now();
    const elapsed = (now - this.since) / 1000;
    if (elapsed < 0.5) return;
    this.fps = this.frames / elapsed;
    this.stepsPerSecond = this.steps / elapsed;
    this.realTimeFactor = this.simulated / elapsed;
    this.frames = this.steps = this.simulated = 0;
    this.since = now;
    this.el.textContent =
      `${this.fps.toFixed(0)} fps · ${Math.round(this.stepsPerSecond)} steps/s · ` +
      `${this.realTimeFactor.toFixed(2)}× real time · ${status()}`;
  }
}

/** Calls `onFile` for a file dropped anywhere on the page. */
export function acceptDroppedFiles(target: HTMLElement, onFile: (file: File) => void): void {
  const hint = document.getElementById('drop-hint');
  target.addEventListener('dragover', (e) => {
    e.preventDefault();
    hint?.classList.add('visible');
  });
  target.addEventListener('dragleave', (e) => {
    if (e.target === target || e.relatedTarget === null) hint?.classList.remove('visible');
  });
  target.addEventListener('drop', (e) => {
    e.preventDefault();
    hint?.classList.remove('visible');
    const file = e.dataTransfer?.files[0];
    if (file) onFile(file);
  });
}

export function toggleHelp(force?: boolean): void {
  document.getElementById('help')?.classList.toggle('visible', force);
}
