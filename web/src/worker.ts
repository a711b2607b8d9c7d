// The stepping worker: owns the simulation that steps, advances it so that simulated time
// follows the wall clock (times a speed), and sends the page the latest state whenever the page
// has drawn the one before. Physics runs here, on its own core, so drawing never waits for it.
import init, { JelloSim } from './wasm/jello_wasm.js';
import type { FromWorker, Parameters, Snapshot, ToWorker } from './protocol';

/** The most simulated time owed to the wall clock (s, at speed 1): a scene too heavy to keep up
 *  runs slower than real time instead of racing to catch up later, and after a stall (a hidden
 *  tab) it resumes where it was. */
const MAX_BACKLOG = 0.25;
/** Stepping time between looks at the message queue (ms): requests are answered within it. */
const SLICE_MS = 12;
/** Most steps per call into the core, so the slice is checked often. */
const MAX_CHUNK = 32;

let sim: JelloSim | undefined;
let epoch = 0;
let paused = false;
let speed = 1;
/** Simulated seconds owed to the wall clock, and when that was last brought up to date. */
let owed = 0;
let lastClock = performance.now();
/** Wall time of one step (ms), a moving average: calls into the core are sized by it. */
let msPerStep = 0.05;
/** Whether the page drew the last state sent; steps taken since it was sent. */
let acked = true;
let taken = 0;
let pendingState = false;
let timer: ReturnType<typeof setTimeout> | undefined;

const ready = init();

function post(message: FromWorker, transfer: Transferable[] = []): void {
  (self as unknown as Worker).postMessage(message, transfer);
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
    blownUp: sim.blownUp,
    message: sim.blowUpMessage(),
    suggestedDt: sim.suggestedDt(),
  };
  post({ type: 'state', ...state }, [positions.buffer, surface.buffer]);
  taken = 0;
  acked = false;
  pendingState = false;
}

function applyParameters(s: JelloSim, p: Parameters): void {
  s.setParameters(p.integrator, p.dt, p.stiffness, p.damping, p.mass);
}

/** Steps for up to one slice, then looks at messages again. */
function tick(): void {
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
  owed = Math.max(0, owed);
  sendState(sim.blownUp);
  schedule(0);
}

function schedule(ms: number): void {
  if (timer === undefined && sim && !paused && !sim.blownUp) timer = setTimeout(tick, ms);
}

function restartClock(): void {
  owed = 0;
  lastClock = performance.now();
}

function handle(m: ToWorker): void {
  switch (m.type) {
    case 'load': {
      const next = m.source.kind === 'text' ? JelloSim.load(m.source.text, m.source.name) : JelloSim.cube(m.source.n);
      if (m.parameters) applyParameters(next, m.parameters);
      sim?.free();
      sim = next;
      epoch = m.epoch;
      taken = 0;
      restartClock();
      sendState(true);
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
      restartClock();
      sendState(true);
      break;
    case 'reset':
      if (!sim) return;
      epoch = m.epoch;
      sim.reset();
      if (m.parameters) applyParameters(sim, m.parameters);
      taken = 0;
      restartClock();
      sendState(true);
      break;
    case 'step':
      if (!sim) return;
      epoch = m.epoch;
      taken += sim.step(m.n);
      sendState(true);
      break;
    case 'pulls':
      sim?.setPulls(m.points, m.targets, m.stiffness, m.damping);
      break;
    case 'push':
      sim?.setPush(m.body, m.ax, m.ay, m.az);
      break;
    case 'save':
      try {
        if (!sim) throw new Error('nothing loaded');
        const text = sim.isScene ? sim.toSceneText() : sim.toWorldText();
        post({ type: 'saved', id: m.id, text, time: sim.time });
      } catch (e) {
        post({ type: 'saved', id: m.id, error: e instanceof Error ? e.message : String(e) });
      }
      break;
    case 'ack':
      acked = true;
      if (pendingState) sendState(true);
      break;
  }
  schedule(0);
}

self.onmessage = (e: MessageEvent<ToWorker>) => {
  // Messages wait for the core; they arrive and are handled in order.
  void ready.then(() => {
    try {
      handle(e.data);
    } catch (err) {
      // The page checks every request against its own copy first, so this is unexpected; say
      // so rather than stop stepping silently.
      post({ type: 'error', epoch, message: err instanceof Error ? err.message : String(err) });
    }
  });
};

void ready.then(() => post({ type: 'ready' }));
