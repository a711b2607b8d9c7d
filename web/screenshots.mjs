// Screenshots of the example scenes in the viewer, for docs/viewer.md: `jello view` on a free port
// of 127.0.0.1, headless Chromium (no WebGPU: the wasm core steps), an 800×500 page. Each scene is
// loaded, paused, stepped exactly SECONDS of simulated time (whatever this machine's speed) with
// the integrator the viewer picks for it, and the page saved as PNG with its name and readout (the
// panel and banners hidden). The camera looks from the home direction (lower for the ring) at the
// bodies, as near as shows all their skins below the name and readout, or with `--camera home` is
// the home camera itself (`e`).
// Usage: node web/screenshots.mjs [--seconds S] [--camera bodies|home] [--out DIR] [--dist DIR]
//                                 [scene.toml[@S] …]
//   scene@S: S seconds for that scene (a scene given twice gets its time in its file name);
//   --dist: another build of the viewer (`jello view --dist`);
//   after scripts/web.sh and cargo build --release (scripts/screenshots.sh does both).
import { mkdirSync } from 'node:fs';
import { join, resolve } from 'node:path';
import { parseArgs } from 'node:util';
import { launch, openViewer } from './tests/browser.mjs';
import { ROOT, startViewer } from './tests/server.mjs';

/** The contact examples (stack.toml as the cubes land on the ball: by 3 s they have slid off it
 *  apart), and the torus alone. */
const SCENES = ['stack.toml@0.4', 'tower.toml', 'pile.toml', 'ring.toml', 'torus.toml'];
/** Degrees above the floor the camera looks from, where not the home camera's 25.7: the ring
 *  under its weight is seen from the side. */
const ELEVATION = { 'ring.toml': 5 };
const { values, positionals } = parseArgs({
  options: {
    seconds: { type: 'string', default: '3' },
    camera: { type: 'string', default: 'bodies' },
    dist: { type: 'string' },
    out: { type: 'string', default: join(ROOT, 'docs', 'images') },
  },
  allowPositionals: true,
});
const seconds = Number(values.seconds);
if (!(seconds >= 0)) throw new Error(`--seconds: not a time: ${values.seconds}`);
if (!['bodies', 'home'].includes(values.camera)) throw new Error(`--camera: bodies or home, not ${values.camera}`);
const out = resolve(values.out);
mkdirSync(out, { recursive: true });
const scenes = (positionals.length > 0 ? positionals : SCENES).map((arg) => {
  const [name, time] = arg.split('@');
  const t = time === undefined ? seconds : Number(time);
  if (!(t >= 0)) throw new Error(`${arg}: not a time`);
  return { name, seconds: t };
});
const twice = new Set(scenes.map((s) => s.name).filter((n, i, all) => all.indexOf(n) !== i));

const server = await startViewer([
  join(ROOT, 'examples', scenes[0].name),
  ...(values.dist ? ['--dist', resolve(values.dist)] : []),
]);
const browser = await launch();
let failed = false;
try {
  for (const { name, seconds } of scenes) {
    const { page, errors } = await openViewer(browser.context, server.url);
    await page.setViewportSize({ width: 800, height: 500 });
    // Without the panel the name and readout may run across the page (they wrap short of it).
    await page.addStyleTag({
      content: '#panel, #banners { visibility: hidden !important; } #hud { right: 10px !important; }',
    });
    await page.evaluate(async (name) => {
      const app = window.jello;
      app.paused = true;
      if (app.sim.name !== name) await app.loadUrl(`examples/${name}`, name);
      if (app.sim.name !== name) throw new Error(`${name} did not load`);
      app.reset();
      await app.settled();
    }, name);
    const started = performance.now();
    // A tenth of a second at a time, so the worker sends states (and a stop shows) as it goes.
    const info = await page.evaluate(async ([seconds, camera, elevation]) => {
      const app = window.jello;
      const dt = () => app.sim.dt;
      while (app.sim.time < seconds - 1e-9 && !app.sim.blownUp) {
        const steps = Math.max(1, Math.round(Math.min(0.1, seconds - app.sim.time) / dt()));
        await app.runner.stepExactly(steps);
      }
      await app.settled();
      if (camera === 'bodies') {
        const p = app.sim.surfacePositions();
        const box = [Infinity, Infinity, Infinity, -Infinity, -Infinity, -Infinity];
        for (let i = 0; i < p.length; i++) {
          box[i % 3] = Math.min(box[i % 3], p[i]);
          box[3 + (i % 3)] = Math.max(box[3 + (i % 3)], p[i]);
        }
        const { camera, controls } = app.viewer;
        app.viewer.frameBox(box);
        if (elevation !== undefined) {
          const offset = camera.position.clone().sub(controls.target);
          const flat = Math.hypot(offset.x, offset.y);
          const e = (elevation * Math.PI) / 180;
          offset.set((offset.x / flat) * Math.cos(e), (offset.y / flat) * Math.cos(e), Math.sin(e)).multiplyScalar(offset.length());
          camera.position.copy(controls.target).add(offset);
          controls.update();
        }
        // Then nearer or further, and aside, until the skins fill the canvas below the name and
        // readout (x within ±0.75, y from -0.8 to 0.55 in normalised device coordinates).
        const [left, right, bottom, top] = [-0.75, 0.75, -0.8, 0.55];
        for (let round = 0; round < 4; round++) {
          camera.updateMatrixWorld();
          const v = camera.position.clone();
          const [lo, hi] = [[Infinity, Infinity], [-Infinity, -Infinity]];
          for (let i = 0; i < p.length; i += 3) {
            v.set(p[i], p[i + 1], p[i + 2]).project(camera);
            lo[0] = Math.min(lo[0], v.x);
            lo[1] = Math.min(lo[1], v.y);
            hi[0] = Math.max(hi[0], v.x);
            hi[1] = Math.max(hi[1], v.y);
          }
          const offset = camera.position.clone().sub(controls.target);
          const half = offset.length() * Math.tan((camera.fov * Math.PI) / 360);
          const shift = [((lo[0] + hi[0]) - (left + right)) / 2, ((lo[1] + hi[1]) - (bottom + top)) / 2];
          const rightward = v.setFromMatrixColumn(camera.matrixWorld, 0).clone();
          const upward = v.setFromMatrixColumn(camera.matrixWorld, 1).clone();
          const move = rightward.multiplyScalar(shift[0] * half * camera.aspect).add(upward.multiplyScalar(shift[1] * half));
          controls.target.add(move);
          const scale = Math.max((hi[0] - lo[0]) / (right - left), (hi[1] - lo[1]) / (top - bottom));
          camera.position.copy(controls.target).add(offset.multiplyScalar(scale));
          controls.update();
        }
      } else {
        app.viewer.resetCamera();
      }
      // Drawn, and the readout refreshed with nothing stepping (it averages over half a second).
      await new Promise((r) => setTimeout(r, 1200));
      await new Promise(requestAnimationFrame);
      return {
        time: app.sim.time,
        steps: app.sim.steps,
        blownUp: app.sim.blownUp,
        integrator: app.parameters().integrator,
        dt: app.sim.dt,
        bodies: app.sim.bodyNames().length,
      };
    }, [seconds, values.camera, ELEVATION[name]]);
    const stem = name.replace(/\.toml$/, '') + (twice.has(name) ? `-${seconds}s` : '');
    const file = join(out, `viewer-${stem}.png`);
    await page.screenshot({ path: file });
    const wall = ((performance.now() - started) / 1000).toFixed(1);
    console.log(
      `${name}: ${info.bodies} bodies, ${info.integrator} at dt ${info.dt} s, t = ${info.time.toFixed(3)} s ` +
        `(${info.steps} steps, ${wall} s)${info.blownUp ? ' BLEW UP' : ''} -> ${file}`,
    );
    if (info.blownUp || errors.length > 0) {
      failed = true;
      for (const e of errors) console.error(`  ${e}`);
    }
    await page.close();
  }
} finally {
  await browser.close();
  await server.stop();
}
if (failed) process.exit(1);
