// Measures the viewer in headless Chromium on this machine (README, "Measurements"):
//   1. the classic world (examples/jello.w) in the running viewer at speed 1: frame rate, steps/s
//      and the real-time factor (simulated seconds per wall second) from the page's readout;
//   2. raw stepping speed of the wasm core on that world, nothing drawn;
//   3. n×n×n cubes (JelloSim.cube(n), the panel's "build n³ cube") with each integrator (RK4 at
//      the cube's own dt, BackwardEuler and SDIRK2 at 1/60 s, BackwardEuler also at the panel's
//      looser tolerances 1e-5 and 1e-3 m/s): real-time factor in the running viewer, to find the
//      largest n that keeps up with the wall clock;
//   4. the example scenes, and a 20 000-point scene (`jello shape blob` voxelised at 39 cells by
//      `jello create`), lit, in the running viewer (with the implicit integrator the viewer picks
//      for it, then with the file's own), and the large one's core alone.
// The simulation steps in the page's Web Worker; "core only" rows step a JelloSim on the page's
// own thread, nothing drawn.
// Usage: node bench/measure.mjs [SECONDS_PER_RUN]   (after scripts/web.sh and cargo build --release)
import { launch, openViewer } from '../tests/browser.mjs';
import { ROOT, startViewer } from '../tests/server.mjs';
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { JELLO } from '../tests/server.mjs';

const seconds = Number(process.argv[2] ?? 8);
const server = await startViewer([join(ROOT, 'examples', 'jello.w')]);
const browser = await launch();
try {
  const { page, errors } = await openViewer(browser.context, server.url);

  /** Average fps, steps/s and real-time factor over `seconds`, after a 2 s warm-up. */
  const run = async () => {
    await page.waitForTimeout(2000);
    return page.evaluate(async (seconds) => {
      const app = window.jello;
      const t0 = performance.now();
      const [s0, f0] = [app.sim.steps, app.sim.time];
      let frames = 0;
      await new Promise((done) => {
        const tick = () => (performance.now() - t0 < seconds * 1000 ? (frames++, requestAnimationFrame(tick)) : done());
        requestAnimationFrame(tick);
      });
      const wall = (performance.now() - t0) / 1000;
      return {
        fps: frames / wall,
        stepsPerSecond: (app.sim.steps - s0) / wall,
        realTime: (app.sim.time - f0) / wall,
        dt: app.sim.dt,
        blownUp: app.sim.blownUp,
      };
    }, seconds);
  };
  const fmt = (r) =>
    `${r.fps.toFixed(1)} fps, ${Math.round(r.stepsPerSecond)} steps/s at dt ${r.dt}, ${r.realTime.toFixed(2)}× real time${r.blownUp ? ' (BLEW UP)' : ''}`;

  console.log(`classic jello.w, lit:        ${fmt(await run())}`);
  await page.keyboard.press('v');
  console.log(`classic jello.w, wireframe:  ${fmt(await run())}`);
  await page.keyboard.press('v');

  const raw = await page.evaluate(async (seconds) => {
    const app = window.jello;
    app.paused = true;
    const text = await (await fetch('examples/jello.w')).text();
    const sim = app.sim.copy.constructor.fromWorld(text, 'jello.w');
    const t0 = performance.now();
    let steps = 0;
    while (performance.now() - t0 < seconds * 1000) steps += sim.step(100);
    const rate = steps / ((performance.now() - t0) / 1000);
    sim.free();
    app.paused = false;
    return rate;
  }, Math.min(seconds, 5));
  console.log(`classic jello.w, core only:  ${Math.round(raw)} steps/s = ${(raw * 0.0005).toFixed(2)}× real time`);

  // The largest cube that keeps up (≥ 0.95× real time), per integrator.
  const largest = {};
  const methods = [
    ['RK4', undefined, 1e-9],
    ['BackwardEuler', 1 / 60, 1e-9],
    ['BackwardEuler', 1 / 60, 1e-5],
    ['BackwardEuler', 1 / 60, 1e-3],
    ['SDIRK2', 1 / 60, 1e-9],
  ];
  for (const [integrator, dt, tolerance] of methods) {
    const label = tolerance === 1e-9 ? integrator : `${integrator} ${tolerance}`;
    for (const n of [6, 7, 8, 9, 10, 11, 12, 14, 16, 20, 24, 28, 32]) {
      await page.evaluate(
        ([n, integrator, dt, tolerance]) => {
          const app = window.jello;
          app.loadCube(n);
          // The cube's own RK4 step (the viewer would pick the implicit method above 8³).
          if (integrator === 'RK4') document.querySelector('.banner-integrator button')?.click();
          else app.setParameters({ ...app.parameters(), integrator, dt, tolerance });
        },
        [n, integrator, dt, tolerance],
      );
      const r = await run();
      console.log(`cube ${String(n).padStart(2)}³ = ${String(n ** 3).padStart(5)} points, ${label.padEnd(18)}: ${fmt(r)}`);
      if (r.realTime >= 0.95 && !r.blownUp) largest[label] = n;
      if (r.realTime < 0.5) break;
    }
  }
  console.log(`largest cube in real time: ${Object.entries(largest).map(([i, n]) => `${i} ${n}³`).join(', ')}`);

  for (const name of ['torus.toml', 'blob.toml', 'mould.toml', 'stack.toml']) {
    await page.evaluate((name) => window.jello.loadUrl(`examples/${name}`, name), name);
    const r = await run();
    const points = await page.evaluate(() => window.jello.sim.activePoints().reduce((s, a) => s + a, 0));
    const chosen = await page.evaluate(() => window.jello.parameters().integrator);
    console.log(`${name.padEnd(11)} ${String(points).padStart(5)} points, ${chosen}: ${fmt(r)}`);
    // Where the viewer chose the implicit method, the file's own too.
    if (await page.evaluate(() => document.querySelector('.banner-integrator button') !== null)) {
      await page.evaluate(() => document.querySelector('.banner-integrator button').click());
      const own = await page.evaluate(() => window.jello.parameters().integrator);
      console.log(`${name.padEnd(11)} ${String(points).padStart(5)} points, ${own}: ${fmt(await run())}`);
    }
  }

  // The large scene: made here, loaded as a dropped file would be.
  const dir = mkdtempSync(join(tmpdir(), 'jello-measure-'));
  execFileSync(JELLO, ['shape', 'blob', join(dir, 'blob.obj'), '--detail', '8']);
  const jelly = ['--density', '1000', '--modulus', '2e5', '--viscosity', '40'];
  execFileSync(JELLO, ['create', join(dir, 'big.toml'), '--dt', '0.0007', '--k-collision', '2e5', '--d-collision', '50',
    '--mesh', join(dir, 'blob.obj'), '--cells', '39', '--at', '0,0,-1', ...jelly]);
  const big = readFileSync(join(dir, 'big.toml'), 'utf8');
  await page.evaluate((text) => window.jello.loadText(text, 'big.toml'), big);
  const points = await page.evaluate(() => window.jello.sim.activePoints().reduce((s, a) => s + a, 0));
  const integrator = await page.evaluate(() => window.jello.parameters().integrator);
  console.log(`blob at 39 cells, ${points} points, ${integrator}, lit:      ${fmt(await run())}`);
  await page.keyboard.press('v');
  console.log(`blob at 39 cells, ${points} points, ${integrator}, wireframe: ${fmt(await run())}`);
  await page.keyboard.press('v');
  await page.evaluate(() => document.querySelector('.banner-integrator button')?.click());
  const own = await page.evaluate(() => window.jello.parameters().integrator);
  console.log(`blob at 39 cells, ${points} points, ${own}, lit:      ${fmt(await run())}`);
  const bigRaw = await page.evaluate(async ([seconds, text]) => {
    const app = window.jello;
    app.paused = true;
    const sim = app.sim.copy.constructor.fromScene(text, 'big.toml');
    const t0 = performance.now();
    let steps = 0;
    while (performance.now() - t0 < seconds * 1000) steps += sim.step(5);
    sim.free();
    app.paused = false;
    return steps / ((performance.now() - t0) / 1000);
  }, [Math.min(seconds, 5), big]);
  console.log(`blob at 39 cells, core only: ${bigRaw.toFixed(1)} steps/s = ${(bigRaw * 0.0007).toFixed(3)}× real time`);
  if (errors.length) console.log('page errors:', errors);
} finally {
  await browser.close();
  await server.stop();
}
