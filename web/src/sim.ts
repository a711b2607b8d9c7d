// Simulation glue. The simulation steps in a Web Worker (worker.ts), following the wall clock
// times a speed multiplier, so drawing never waits for physics and a second core does the
// stepping. The page keeps its own copy of the simulation, loaded from the same source and never
// stepped: it answers at once what stepping does not change (the mesh, the springs drawn, the
// bodies) and checks every request before it goes to the worker, so a bad value throws here, with
// the core's message, and changes nothing. All physics is in Rust.
import init, { JelloSim } from './wasm/jello_wasm.js';
import { applyParameters, type Backend, type Device, type FromWorker, type Parameters, type Snapshot, type Source, type ToWorker } from './protocol';
import type { SceneData } from './render';

export { JelloSim };
export type { Backend, Device, Parameters, Source };

/** Loads and instantiates the wasm module (once). */
export async function loadCore(): Promise<void> {
  await init();
}

/** Above this many points a scene starts with the implicit integrator at frame-rate steps
 *  (issue 9): an explicit method's small steps cannot keep up with the wall clock there. */
export const IMPLICIT_ABOVE_POINTS = 512;
/** The integrator, step and tolerance such scenes start with: 1e-5 m/s moves no point visibly
 *  (4e-9 m after 2 s of a 16³ drop against the core's default 1e-9) and runs a 12³ cube in real
 *  time where 1e-9 runs 11³ (BENCHMARKS.md, "The viewer in Chromium"). */
export const IMPLICIT_DEFAULT = { integrator: 'BackwardEuler', dt: 1 / 60, tolerance: 1e-5 };

/** The state as the page's copy has it (at load or reset): shown until the worker sends its
 *  own. */
function snapshotOf(sim: JelloSim, epoch: number): Snapshot {
  return {
    epoch,
    positions: sim.positions(),
    surface: sim.surfacePositions(),
    time: sim.time,
    steps: sim.steps,
    taken: 0,
    newtonIterations: sim.newtonIterations,
    blownUp: false,
  };
}

/** The simulation as the rest of the page sees it: what does not change while stepping comes
 *  from the page's copy, the state from the latest the worker sent. */
export class SimView {
  constructor(
    readonly copy: JelloSim,
    private readonly runner: Runner,
  ) {}

  private get state(): Snapshot {
    return this.runner.state;
  }

  // ---- The state (from the worker) ----
  positions(): Float32Array {
    return this.state.positions;
  }
  surfacePositions(): Float32Array {
    return this.state.surface;
  }
  get time(): number {
    return this.state.time;
  }
  get steps(): number {
    return this.state.steps;
  }
  get blownUp(): boolean {
    return this.state.blownUp;
  }
  /** The implicit solver's Newton iterations since load, reset or a change of parameters. */
  get newtonIterations(): number {
    return this.state.newtonIterations;
  }
  blowUpMessage(): string | undefined {
    return this.state.message;
  }
  suggestedDt(): number | undefined {
    return this.state.suggestedDt;
  }
  /** What steps (the worker's choice); undefined until it has chosen. */
  get backend(): Backend | undefined {
    return this.state.backend;
  }

  // ---- Parameters (the copy is kept equal to the worker's) ----
  get integrator(): string {
    return this.copy.integrator;
  }
  get dt(): number {
    return this.copy.dt;
  }

  // ---- What stepping does not change ----
  get name(): string {
    return this.copy.name;
  }
  get isScene(): boolean {
    return this.copy.isScene;
  }
  /** Lattice points, active or not: the length of the per-point arrays. */
  get pointCount(): number {
    return this.copy.pointCount;
  }
  /** Points that take part, as `jello info` counts them: a body voxelised from a mesh keeps a
   *  whole lattice whose points outside its cells never move ([`activePoints`] marks them). */
  get activePointCount(): number {
    return activePointCount(this.copy);
  }
  get surfaceVertexCount(): number {
    return this.copy.surfaceVertexCount;
  }
  get fieldRes(): number {
    return this.copy.fieldRes;
  }
  bodyNames(): string[] {
    return this.copy.bodyNames();
  }
  bodyMass(body: number): number {
    return this.copy.bodyMass(body);
  }
  pointBodies(): Uint32Array {
    return this.copy.pointBodies();
  }
  activePoints(): Uint8Array {
    return this.copy.activePoints();
  }
  restPositions(): Float32Array {
    return this.copy.restPositions();
  }
  surfaceTriangles(): Uint32Array {
    return this.copy.surfaceTriangles();
  }
  surfaceVertexPoint(vertex: number): number {
    return this.copy.surfaceVertexPoint(vertex);
  }
  obstacles(): Float64Array {
    return this.copy.obstacles();
  }

  // ---- Interaction: checked here, applied in the worker ----
  setPulls(points: Uint32Array, targets: Float64Array, stiffness: Float64Array, damping: Float64Array): void {
    this.copy.setPulls(points, targets, stiffness, damping);
    this.runner.send({ type: 'pulls', points, targets, stiffness, damping });
  }
  setPush(body: number, ax: number, ay: number, az: number): void {
    this.copy.setPush(body, ax, ay, az);
    this.runner.send({ type: 'push', body, ax, ay, az });
  }
}

/** Owns the stepping worker and the page's copy of the simulation. */
export class Runner {
  /** The latest state of the current epoch. */
  state: Snapshot;
  /** Set when the worker reports a failure the page's checks did not foresee. */
  onError: (message: string) => void = () => {};
  private _sim: SimView;
  private _paused = false;
  private _hold = false;
  private _speed = 1;
  private _device: Device = 'auto';
  /** Numbers the requests that change the state at once; see protocol.ts. */
  private epoch = 0;
  /** Steps the worker reported since the page last asked ([`Runner.advance`]). */
  private newSteps = 0;
  /** States received that the page has not drawn yet (the worker waits for an ack). */
  private unacked = false;
  private readonly waiting: { epoch: number; resolve: (steps: number) => void; steps: number }[] = [];
  private readonly saves = new Map<number, { resolve: (r: { text: string; time: number }) => void; reject: (e: Error) => void }>();
  private nextSave = 0;

  private constructor(
    private readonly worker: Worker,
    /** The browser's WebGPU adapter, as it names itself; undefined without one. */
    readonly webgpu: string | undefined,
    copy: JelloSim,
    source: Source,
    parameters: Parameters | undefined,
  ) {
    this._sim = new SimView(copy, this);
    this.state = snapshotOf(copy, 0);
    worker.onmessage = (e: MessageEvent<FromWorker>) => this.receive(e.data);
    worker.onerror = (e) => this.onError(e.message || 'the stepping worker failed');
    this.send({ type: 'load', epoch: ++this.epoch, source, parameters });
  }

  /** Starts the worker and loads `copy`'s source in it (with `parameters` applied, if given). */
  static async start(copy: JelloSim, source: Source, parameters?: Parameters): Promise<Runner> {
    const worker = new Worker(new URL('./worker.ts', import.meta.url), { type: 'module' });
    const webgpu = await new Promise<string | undefined>((resolve, reject) => {
      worker.onmessage = (e: MessageEvent<FromWorker>) => {
        if (e.data.type === 'ready') resolve(e.data.webgpu);
      };
      worker.onerror = (e) => reject(new Error(`the stepping worker could not start: ${e.message}`));
    });
    return new Runner(worker, webgpu, copy, source, parameters);
  }

  get sim(): SimView {
    return this._sim;
  }

  get paused(): boolean {
    return this._paused;
  }
  set paused(p: boolean) {
    if (p === this._paused) return;
    this._paused = p;
    this.sendRun();
  }

  /** Stops stepping with the wall clock, whatever `paused` says (while frames are recorded,
   *  which advance by exact steps). */
  get hold(): boolean {
    return this._hold;
  }
  set hold(h: boolean) {
    if (h === this._hold) return;
    this._hold = h;
    this.sendRun();
  }

  /** Simulated seconds per wall-clock second. */
  get speed(): number {
    return this._speed;
  }
  set speed(s: number) {
    this._speed = s;
    this.sendRun();
  }

  /** Which device steps (see [`Device`]). */
  get device(): Device {
    return this._device;
  }
  set device(d: Device) {
    if (d === this._device) return;
    this._device = d;
    this.send({ type: 'device', epoch: ++this.epoch, device: d });
  }

  /** Whether the GPU would step `sim` with the current device setting (the browser has WebGPU
   *  and the GPU covers the model). */
  gpuWouldStep(sim: JelloSim): boolean {
    return this._device === 'auto' && this.webgpu !== undefined && sim.gpuRefusal() === undefined;
  }

  send(message: ToWorker): void {
    this.worker.postMessage(message);
  }

  private sendRun(): void {
    this.send({ type: 'run', epoch: ++this.epoch, paused: this._paused || this._hold, speed: this._speed });
  }

  /** Replaces the simulation (the old copy is freed); `parameters` are applied on top of the
   *  source's own. */
  replace(copy: JelloSim, source: Source, parameters?: Parameters): void {
    this._sim.copy.free();
    this._sim = new SimView(copy, this);
    this.epoch++;
    this.state = { ...snapshotOf(copy, this.epoch), backend: this.state.backend };
    this.newSteps = 0;
    this.send({ type: 'load', epoch: this.epoch, source, parameters });
  }

  parameters(): Parameters {
    const s = this._sim.copy;
    return { integrator: s.integrator, dt: s.dt, stiffness: s.stiffness, damping: s.damping, mass: s.mass, tolerance: s.tolerance };
  }

  /** Throws (with the core's message) and changes nothing when a value is out of range. Clears
   *  a blow-up: stepping resumes from the last good state. */
  setParameters(p: Parameters): void {
    applyParameters(this._sim.copy, p);
    this.state = { ...this.state, blownUp: false, message: undefined, suggestedDt: undefined, epoch: ++this.epoch };
    this.send({ type: 'parameters', epoch: this.epoch, parameters: p });
  }

  /** Back to the source as loaded, then `parameters` (if given) on top. */
  reset(parameters?: Parameters): void {
    const copy = this._sim.copy;
    copy.reset();
    if (parameters) applyParameters(copy, parameters);
    this.epoch++;
    this.state = { ...snapshotOf(copy, this.epoch), backend: this.state.backend };
    this.newSteps = 0;
    this.send({ type: 'reset', epoch: this.epoch, parameters });
  }

  /** The steps taken since the last call (for the readout); acknowledges the state drawn, so
   *  the worker sends the next. */
  advance(): number {
    const steps = this.newSteps;
    this.newSteps = 0;
    if (this.unacked) {
      this.unacked = false;
      this.send({ type: 'ack' });
    }
    return steps;
  }

  /** Exactly `n` steps (the single-step key, frame capture); resolves to the steps taken once
   *  the worker has sent the state after them. */
  stepExactly(n: number): Promise<number> {
    const epoch = ++this.epoch;
    this.send({ type: 'step', epoch, n });
    return new Promise((resolve) => this.waiting.push({ epoch, resolve, steps: 0 }));
  }

  /** Exactly `seconds` of simulated time (rounded to whole steps), for frame capture. */
  advanceExactly(seconds: number): Promise<number> {
    return this.stepExactly(Math.max(1, Math.round(seconds / this._sim.dt)));
  }

  /** Resolves once the worker has handled every request made so far (and the state shown is
   *  from after them). */
  settled(): Promise<void> {
    return this.stepExactly(0).then(() => undefined);
  }

  /** The current state as text: a scene file for a scene, else a world file. */
  save(): Promise<{ text: string; time: number }> {
    const id = this.nextSave++;
    this.send({ type: 'save', id });
    return new Promise((resolve, reject) => this.saves.set(id, { resolve, reject }));
  }

  private receive(m: FromWorker): void {
    switch (m.type) {
      case 'state': {
        this.unacked = true;
        if (m.epoch < this.epoch) {
          // Sent before the page's latest request: not what the page shows any more.
          this.send({ type: 'ack' });
          this.unacked = false;
          return;
        }
        const { type: _, ...state } = m;
        this.state = state;
        this.newSteps += m.taken;
        const done = this.waiting.filter((w) => w.epoch <= m.epoch);
        for (const w of done) {
          this.waiting.splice(this.waiting.indexOf(w), 1);
          w.resolve(m.taken);
        }
        break;
      }
      case 'saved': {
        const pending = this.saves.get(m.id);
        this.saves.delete(m.id);
        if (!pending) return;
        if (m.text !== undefined) pending.resolve({ text: m.text, time: m.time ?? 0 });
        else pending.reject(new Error(m.error ?? 'unknown error'));
        break;
      }
      case 'error':
        this.onError(m.message);
        break;
      case 'ready':
        break;
    }
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

/** The points of `sim` that take part, as `jello info` counts them (a body voxelised from a mesh
 *  keeps a whole lattice whose points outside its cells never move). */
export function activePointCount(sim: JelloSim): number {
  let n = 0;
  for (const a of sim.activePoints()) n += a;
  return n;
}

/** Parses a world file, or a scene file when the name ends in `.toml`; throws an Error whose
 *  message names the file and line (and column, for a scene). */
export function parseWorld(text: string, name: string): JelloSim {
  return JelloSim.load(text, name);
}

/** The parameters a freshly loaded `sim` starts with in the viewer: its own, except that a
 *  scene of more than [`IMPLICIT_ABOVE_POINTS`] active points stepped by an explicit method on the CPU
 *  starts with the implicit default (on the GPU, `onGpu`, its own explicit steps keep up).
 *  `undefined` when its own stand. */
export function startingParameters(sim: JelloSim, onGpu: boolean): Parameters | undefined {
  if (activePointCount(sim) <= IMPLICIT_ABOVE_POINTS || sim.isImplicit || onGpu) return undefined;
  return { ...IMPLICIT_DEFAULT, stiffness: sim.stiffness, damping: sim.damping, mass: sim.mass };
}
