// The stepping worker: owns the simulation that steps, advances it so that simulated time
// follows the wall clock (times a speed), and sends the page the latest state whenever the page
// has drawn the one before. Physics runs here, on its own core, so drawing never waits for it.
//
// Two backends step: the GPU through WebGPU (jello-gpu's WGSL, f32), when the browser has an
// adapter and the GPU steps the model, and the wasm core (f64) otherwise. Either way the wasm
// `JelloSim` holds the state the page is sent: after each call the GPU's state is read back into
// it, so saving, the skin and a switch of backend carry on from the same state.
import init, { JelloGpu, JelloSim } from './wasm/jello_wasm.js';
import { applyParameters, type Backend, type Device, type FromWorker, type Snapshot, type ToWorker } from './protocol';

/** The most simulated time owed to the wall clock (s, at speed 1): a scene too heavy to keep up
 *  runs slower than real time instead of racing to catch up later, and after a stall (a hidden
 *  tab) it resumes where it was. */
const MAX_BACKLOG = 0.25;
/** Stepping time between looks at the message queue (ms): requests are answered within it. */
const SLICE_MS = 12;
/** Most steps per call into the core, so the slice is checked often. */
const MAX_CHUNK = 32;
/** A call to the GPU costs a submission and a readback whatever its steps: its steps double
 *  while calls take less than this (ms) and halve when one takes over twice as long. */
const GPU_CALL_MS = 24;
const MAX_GPU_CHUNK = 4096;

let sim: JelloSim | undefined;
/** The GPU copy stepping `sim`'s model, when the GPU steps. */
let gpu: JelloGpu | undefined;
let device: Device = 'auto';
let backend: Backend | undefined;
/** The browser's WebGPU adapter, as it names itself; undefined without one. */
let webgpu: string | undefined;
let epoch = 0;
let paused = false;
let speed = 1;
/** Simulated seconds owed to the wall clock, and when that was last brought up to date. */
let owed = 0;
let lastClock = performance.now();
/** Wall time of one step on the CPU (ms), a moving average: calls into the core are sized by it. */
let msPerStep = 0.05;
/** Steps per call to the GPU, sized by how long calls take: from one, so that a slow adapter
 *  (SwiftShader: 22 ms a step of 8³) keeps the worker answering from its first call. */
let gpuChunk = 1;
/** Whether the page drew the last state sent; steps taken since it was sent. */
let acked = true;
let taken = 0;
let pendingState = false;
let timer: ReturnType<typeof setTimeout> | undefined;

function post(message: FromWorker, transfer: Transferable[] = []): void {
  (self as unknown as Worker).postMessage(message, transfer);
}

function errorText(e: unknown): string {
  return e instanceof Error ? e.message : String(e);
}

/** Asks the browser for a WebGPU adapter: its name, or undefined when there is none. */
async function probeWebGpu(): Promise<string | undefined> {
  type Adapter = { info?: { vendor?: string; architecture?: string; description?: string } };
  const gpuApi = (self.navigator as unknown as { gpu?: { requestAdapter(): Promise<Adapter | null> } }).gpu;
  if (!gpuApi) return undefined;
  try {
    const adapter = await gpuApi.requestAdapter();
    if (!adapter) return undefined;
    const info = adapter.info ?? {};
    const name = [info.vendor, info.architecture, info.description].filter((s) => s).join(' ');
    return name || 'unnamed adapter';
  } catch {
    return undefined;
  }
}

/** Sends the state now (after a request), or once the page has drawn the last one. */
function sendState(now: boolean): void {
  if (!sim) return;
  if (!now && !acked) {
    pendingState = true;
    return;
  }
  const positions = sim.positions();
  const surface = sim.surfacePositions();
  const state: Snapshot = {
    epoch,
    positions,
    surface,
    time: sim.time,
    steps: sim.steps,
    taken,
    newtonIterations: sim.newtonIterations,
    blownUp: sim.blownUp,
    message: sim.blowUpMessage(),
    suggestedDt: sim.suggestedDt(),
    backend,
  };
  post({ type: 'state', ...state }, [positions.buffer, surface.buffer]);
  taken = 0;
  acked = false;
  pendingState = false;
}

/** Puts `sim` on the GPU when the device setting, the browser and the model allow it, else on
 *  the CPU; `backend` says which and why. Called whenever the model changes. */
async function chooseBackend(): Promise<void> {
  gpu?.free();
  gpu = undefined;
  if (!sim) return;
  if (device === 'cpu') {
    backend = { kind: 'wasm', why: 'the CPU was chosen' };
  } else if (webgpu === undefined) {
    backend = { kind: 'wasm', why: 'this browser has no WebGPU adapter' };
  } else {
    try {
      gpu = await JelloGpu.create(sim);
      backend = { kind: 'webgpu', adapter: webgpu, kernel: gpu.kernel };
      gpuChunk = 1;
    } catch (e) {
      backend = { kind: 'wasm', why: errorText(e) };
    }
  }
}

/** The GPU failed while stepping: the CPU carries on from the last state read back. */
function gpuFailed(e: unknown): void {
  gpu?.free();
  gpu = undefined;
  backend = { kind: 'wasm', why: `the GPU failed (${errorText(e)}); the CPU carries on` };
  console.warn(`jello: ${backend.why}`);
}

/** Takes `n` steps on whichever backend steps; returns how many were taken (fewer after a
 *  blow-up: the state is then the last good step). */
async function advance(n: number): Promise<number> {
  if (!sim || n <= 0) return 0;
  if (gpu && !sim.blownUp) {
    try {
      const done = await gpu.step(n);
      sim.adoptGpuState(gpu);
      return done;
    } catch (e) {
      gpuFailed(e);
    }
  }
  return sim.step(n);
}

/** Steps for up to one slice, then looks at messages again. */
async function tick(): Promise<void> {
  timer = undefined;
  if (!sim || paused || sim.blownUp) return;
  const now = performance.now();
  owed = Math.min(owed + ((now - lastClock) / 1000) * speed, MAX_BACKLOG * speed);
  lastClock = now;
  const dt = sim.dt;
  let due = Math.floor(owed / dt);
  if (due === 0) {
    // Ahead of the clock: sleep until the next step is due.
    schedule(((dt - owed) / speed) * 1000);
    return;
  }
  if (gpu) {
    // One call per slice: its steps grow while calls are quick.
    const n = Math.max(1, Math.min(gpuChunk, due));
    const before = performance.now();
    const done = await advance(n);
    const took = performance.now() - before;
    if (took < GPU_CALL_MS && n === gpuChunk) gpuChunk = Math.min(MAX_GPU_CHUNK, 2 * gpuChunk);
    else if (took > 2 * GPU_CALL_MS) gpuChunk = Math.max(1, gpuChunk >> 1);
    taken += done;
    owed -= done * dt;
  } else {
    const start = performance.now();
    while (due > 0) {
      const left = SLICE_MS - (performance.now() - start);
      if (left <= 0) break;
      const n = Math.max(1, Math.min(MAX_CHUNK, due, Math.floor(left / msPerStep)));
      const before = performance.now();
      const done = sim.step(n);
      if (done > 0) msPerStep = 0.7 * msPerStep + (0.3 * (performance.now() - before)) / done;
      taken += done;
      due -= done;
      owed -= done * dt;
      if (done < n) break; // blew up: the state is the last good step
    }
  }
  owed = Math.max(0, owed);
  sendState(sim.blownUp);
  schedule(0);
}

function schedule(ms: number): void {
  if (timer === undefined && sim && !paused && !sim.blownUp) timer = setTimeout(() => enqueue(tick), ms);
}

function restartClock(): void {
  owed = 0;
  lastClock = performance.now();
}

/** After a load, new parameters, a reset or a device change: the backend is chosen again, the
 *  clock starts afresh, and the page gets the state. */
async function modelChanged(): Promise<void> {
  await chooseBackend();
  restartClock();
  sendState(true);
}

async function handle(m: ToWorker): Promise<void> {
  switch (m.type) {
    case 'load': {
      const next = m.source.kind === 'text' ? JelloSim.load(m.source.text, m.source.name) : JelloSim.cube(m.source.n);
      if (m.parameters) applyParameters(next, m.parameters);
      sim?.free();
      sim = next;
      epoch = m.epoch;
      taken = 0;
      await modelChanged();
      break;
    }
    case 'run':
      epoch = m.epoch;
      if (paused && !m.paused) restartClock();
      paused = m.paused;
      speed = m.speed;
      sendState(true);
      break;
    case 'parameters':
      if (!sim) return;
      epoch = m.epoch;
      applyParameters(sim, m.parameters);
      await modelChanged();
      break;
    case 'reset':
      if (!sim) return;
      epoch = m.epoch;
      sim.reset();
      if (m.parameters) applyParameters(sim, m.parameters);
      taken = 0;
      await modelChanged();
      break;
    case 'device':
      epoch = m.epoch;
      device = m.device;
      await modelChanged();
      break;
    case 'step':
      if (!sim) return;
      epoch = m.epoch;
      taken += await advance(m.n);
      sendState(true);
      break;
    case 'pulls':
      sim?.setPulls(m.points, m.targets, m.stiffness, m.damping);
      if (sim && gpu) gpu.setControl(sim);
      break;
    case 'push':
      sim?.setPush(m.body, m.ax, m.ay, m.az);
      if (sim && gpu) gpu.setControl(sim);
      break;
    case 'save':
      try {
        if (!sim) throw new Error('nothing loaded');
        const text = sim.isScene ? sim.toSceneText() : sim.toWorldText();
        post({ type: 'saved', id: m.id, text, time: sim.time });
      } catch (e) {
        post({ type: 'saved', id: m.id, error: errorText(e) });
      }
      break;
    case 'ack':
      acked = true;
      if (pendingState) sendState(true);
      break;
  }
  schedule(0);
}

/** Messages and stepping take turns, in order: a GPU call in flight finishes before the next
 *  message is handled. */
let queue: Promise<void> = (async () => {
  await init();
  webgpu = await probeWebGpu();
  post({ type: 'ready', webgpu });
})();

function enqueue(job: () => Promise<void>): void {
  queue = queue.then(job).catch((err: unknown) => {
    // The page checks every request against its own copy first, so this is unexpected; say
    // so rather than stop stepping silently.
    post({ type: 'error', epoch, message: errorText(err) });
  });
}

self.onmessage = (e: MessageEvent<ToWorker>) => enqueue(() => handle(e.data));
