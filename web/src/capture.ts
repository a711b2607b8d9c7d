// Capture: a PNG screenshot, a numbered PNG frame sequence (000.png, 001.png, … at 15 frames per
// simulated second, at most 300) zipped into one download, and a WebM video where the browser can
// record one.
import { zipSync } from 'fflate';

/** Frames per second of simulated time in a frame sequence. */
export const SEQUENCE_FPS = 15;
/** The most frames a sequence holds (the original assignment's limit). */
export const SEQUENCE_MAX = 300;

/** Offers `blob` to the user as a download named `name`. */
export function download(blob: Blob, name: string): void {
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = name;
  document.body.append(a);
  a.click();
  a.remove();
  // Revoke later: the download starts asynchronously.
  setTimeout(() => URL.revokeObjectURL(url), 10_000);
}

/** Collects PNG frames and zips them. */
export class FrameSequence {
  private frames: Promise<Uint8Array>[] = [];

  get count(): number {
    return this.frames.length;
  }

  get full(): boolean {
    return this.frames.length >= SEQUENCE_MAX;
  }

  add(png: Promise<Blob>): void {
    this.frames.push(png.then(async (b) => new Uint8Array(await b.arrayBuffer())));
  }

  /** The frames as `000.png`, `001.png`, … in one zip (stored, not deflated: PNG is already
   *  compressed). */
  async zip(): Promise<Blob> {
    const frames = await Promise.all(this.frames);
    const files: Record<string, [Uint8Array, { level: 0 }]> = {};
    frames.forEach((png, n) => (files[`${String(n).padStart(3, '0')}.png`] = [png, { level: 0 }]));
    const bytes = zipSync(files);
    return new Blob([bytes.buffer as ArrayBuffer], { type: 'application/zip' });
  }
}

/** The WebM type this browser records, or undefined when it cannot. */
export function webmType(): string | undefined {
  if (typeof MediaRecorder === 'undefined') return undefined;
  return ['video/webm;codecs=vp9', 'video/webm;codecs=vp8', 'video/webm'].find((t) => MediaRecorder.isTypeSupported(t));
}

/** Records the canvas into a WebM video. */
export class VideoRecorder {
  private recorder: MediaRecorder | undefined;
  private chunks: Blob[] = [];

  get recording(): boolean {
    return this.recorder !== undefined;
  }

  /** Starts recording; throws when the browser cannot record WebM. */
  start(canvas: HTMLCanvasElement): void {
    const type = webmType();
    if (!type) throw new Error('this browser cannot record WebM video');
    this.chunks = [];
    const recorder = new MediaRecorder(canvas.captureStream(30), { mimeType: type });
    recorder.ondataavailable = (e) => {
      if (e.data.size > 0) this.chunks.push(e.data);
    };
    recorder.start(1000);
    this.recorder = recorder;
  }

  /** Stops and resolves to the video. */
  stop(): Promise<Blob> {
    const recorder = this.recorder;
    this.recorder = undefined;
    if (!recorder) return Promise.reject(new Error('not recording'));
    return new Promise((resolve) => {
      recorder.onstop = () => resolve(new Blob(this.chunks, { type: 'video/webm' }));
      recorder.stop();
    });
  }
}
