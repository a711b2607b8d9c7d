// Simulation glue: loads the wasm core, owns the current JelloSim, and advances it so that
// simulated time follows the wall clock (times a speed multiplier). All physics is in Rust.
import init, { JelloSim } from './wasm/jello_wasm.js';
import type { SceneData } from './render';

export { JelloSim };

/** Loads and instantiates the wasm module (once). */
export async function loadCore(): Promise<void> {
  await init();
}

/** The longest wall-clock gap one frame makes up for (s): after a stall (a hidden tab, a
 *  breakpoint) the simulation resumes instead of racing to catch up. */
const MAX_FRAME_GAP = 0.25;
/** Stepping time one frame may spend (ms) before the backlog is dropped and the simulation runs
 *  slower than real time; keeps the page responsive for worlds too heavy for this machine. */
const STEP_BUDGET_MS = 40;
/** Most steps per call into the core, so the time budget is checked often. */
const MAX_CHUNK = 32;

export interface Parameters {
  integrator: string;
  dt: number;
  stiffness: number;
  damping: number;
  mass: number;
}

export class Runner {
  paused = false;
  /** Simulated seconds per wall-clock second. */
  speed = 1;
  /** Simulated seconds owed to the wall clock. */
  private owed = 0;
  /** Wall time of one step (ms), a moving average: chunks of steps are sized so that one chunk
   *  does not overrun the frame's stepping budget (a 20 000-point scene takes about 20 ms a
   *  step here, so a fixed chunk of 32 would freeze the page for most of a second). */
  private msPerStep = 0.05;

  constructor(public sim: JelloSim) {}

  /** Replaces the simulation (the old one is freed). */
  replace(sim: JelloSim): void {
    this.sim.free();
    this.sim = sim;
    this.owed = 0;
    this.msPerStep = 0.05;
  }

  parameters(): Parameters {
    const s = this.sim;
    return { integrator: s.integrator, dt: s.dt, stiffness: s.stiffness, damping: s.damping, mass: s.mass };
  }

  /** Throws (with the core's message) and changes nothing when a value is out of range. */
  setParameters(p: Parameters): void {
    this.sim.setParameters(p.integrator, p.dt, p.stiffness, p.damping, p.mass);
    this.owed = 0;
  }

  /** Advances for a frame that took `wallSeconds`; returns the steps taken. */
  advance(wallSeconds: number): number {
    if (this.paused || this.sim.blownUp) {
      this.owed = 0;
      return 0;
    }
    const dt = this.sim.dt;
    this.owed += Math.min(wallSeconds, MAX_FRAME_GAP) * this.speed;
    let due = Math.floor(this.owed / dt);
    const start = performance.now();
    let taken = 0;
    while (due > 0) {
      const left = STEP_BUDGET_MS - (performance.now() - start);
      const n = Math.max(1, Math.min(MAX_CHUNK, due, Math.floor(left / this.msPerStep)));
      const before = performance.now();
      const done = this.sim.step(n);
      if (done > 0) this.msPerStep = 0.7 * this.msPerStep + (0.3 * (performance.now() - before)) / done;
      taken += done;
      due -= done;
      if (done < n) break; // blew up: the state is the last good step
      if (performance.now() - start > STEP_BUDGET_MS) {
        due = 0; // cannot keep up: drop the backlog
        this.owed = 0;
        break;
      }
    }
    this.owed = Math.max(0, this.owed - taken * dt);
    if (due > 0) this.owed = 0;
    return taken;
  }

  /** One step, for the single-step key. */
  stepOnce(): number {
    return this.sim.step(1);
  }

  /** Exactly `seconds` of simulated time (rounded to whole steps), for frame capture. */
  advanceExactly(seconds: number): number {
    const n = Math.max(1, Math.round(seconds / this.sim.dt));
    return this.sim.step(n);
  }
}

/** What the renderer needs of the current world or scene. */
export function sceneData(sim: JelloSim): SceneData {
  return {
    pointCount: sim.pointCount,
    surfaceVertexCount: sim.surfaceVertexCount,
    triangles: sim.surfaceTriangles(),
    surfaceBodies: sim.surfaceBodies(),
    surfacePoints: sim.surfacePoints(),
    springs: [sim.surfaceSprings(0), sim.surfaceSprings(1), sim.surfaceSprings(2)],
    box: sim.boundingBox(),
    plane: sim.plane(),
    field: sim.fieldSamples(),
    fieldRes: sim.fieldRes,
    obstacles: sim.obstacles(),
    pins: sim.pins(),
  };
}

/** Parses a world file, or a scene file when the name ends in `.toml`; throws an Error whose
 *  message names the file and line (and column, for a scene). */
export function parseWorld(text: string, name: string): JelloSim {
  return JelloSim.load(text, name);
}
