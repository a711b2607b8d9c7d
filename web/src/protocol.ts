// The messages between the page and the stepping worker (worker.ts). The worker owns the
// simulation that steps; the page keeps a copy that never steps, for what does not change while
// stepping (the mesh, the springs drawn, the bodies), and draws the latest state the worker sent.

import type { JelloSim } from './wasm/jello_wasm.js';

/** Where a simulation comes from: world or scene text, or the panel's cube. */
export type Source = { kind: 'text'; text: string; name: string } | { kind: 'cube'; n: number };

/** Which device steps: `auto` the GPU (WebGPU, f32) when the browser has an adapter and the GPU
 *  steps the model, else the CPU; `cpu` the wasm core (f64) always. */
export type Device = 'auto' | 'cpu';

/** What steps now: WebGPU (on `adapter`) or the wasm core, and why not the GPU when it could
 *  have been asked to. */
export interface Backend {
  kind: 'webgpu' | 'wasm';
  adapter?: string;
  /** On WebGPU: `resident` (a small lattice inside one workgroup) or `stages`. */
  kernel?: string;
  why?: string;
}

/** The parameters the panel shows and sets. */
export interface Parameters {
  integrator: string;
  dt: number;
  stiffness: number;
  damping: number;
  mass: number;
  /** Residual allowed per point by the implicit integrators (m/s); kept, unused, by explicit ones. */
  tolerance: number;
}

/** Sets `p` on `sim` (the page's copy, or the worker's); throws (with the core's message) and
 *  changes nothing when a value is out of range. */
export function applyParameters(sim: JelloSim, p: Parameters): void {
  sim.setParameters(p.integrator, p.dt, p.stiffness, p.damping, p.mass, p.tolerance);
}

/** From the page to the worker. `epoch` numbers the requests that change the state at once
 *  (a load, a reset, new parameters, a pause, exact steps): the worker tags what it sends with
 *  the epoch of the last one it handled, so the page can tell a state sent before its request
 *  from one sent after. */
export type ToWorker =
  | { type: 'load'; epoch: number; source: Source; parameters?: Parameters }
  | { type: 'run'; epoch: number; paused: boolean; speed: number }
  | { type: 'parameters'; epoch: number; parameters: Parameters }
  | { type: 'reset'; epoch: number; parameters?: Parameters }
  | { type: 'step'; epoch: number; n: number }
  | { type: 'device'; epoch: number; device: Device }
  | { type: 'pulls'; points: Uint32Array; targets: Float64Array; stiffness: Float64Array; damping: Float64Array }
  | { type: 'push'; body: number; ax: number; ay: number; az: number }
  | { type: 'save'; id: number }
  /** The page drew the last state: the worker may send the next. */
  | { type: 'ack' };

/** The state of the simulation at one step, as the worker sends it. */
export interface Snapshot {
  epoch: number;
  /** Lattice point positions (x, y, z per point). */
  positions: Float32Array;
  /** Skin vertex positions (x, y, z per vertex). */
  surface: Float32Array;
  time: number;
  steps: number;
  /** Steps taken since the previous snapshot. */
  taken: number;
  /** The implicit solver's Newton iterations since load, reset or a change of parameters (0
   *  under an explicit integrator or on the GPU). */
  newtonIterations: number;
  blownUp: boolean;
  message?: string;
  suggestedDt?: number;
  /** What stepped; absent until the worker has chosen. */
  backend?: Backend;
}

/** From the worker to the page. */
export type FromWorker =
  /** The worker runs; `webgpu` names the browser's WebGPU adapter, absent when it has none. */
  | { type: 'ready'; webgpu?: string }
  | ({ type: 'state' } & Snapshot)
  | { type: 'saved'; id: number; text?: string; time?: number; error?: string }
  /** A request failed in the worker (it had passed the page's own checks): the message. */
  | { type: 'error'; epoch: number; message: string };
