// The viewer's two backends: with WebGPU (Chromium's SwiftShader adapter, on the CPU) the worker
// steps on the GPU with the same WGSL as the native backend, in f32; without it, on the wasm
// core. The panel says which. Run by scripts/web-test.sh with the other browser tests.
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { after, before, describe, test } from 'node:test';
import { launch, openForTest } from './browser.mjs';
import { clippedLabels } from './labels.mjs';
import { difference, shot } from './pixels.mjs';
import { ROOT, startViewer } from './server.mjs';

const pause = (ms) => new Promise((r) => setTimeout(r, ms));

let server;

before(async () => {
  server = await startViewer([join(ROOT, 'examples', 'jello.w')]);
});

after(async () => {
  await server?.stop();
});

/** Loads the panel's n³ cube (dropped from rest, no contact for a while), paused, on `device`,
 *  and takes `steps` exact steps; resolves to its positions, the backend and the time. */
function cubeAfter(page, n, device, steps) {
  return page.evaluate(
    async ({ n, device, steps }) => {
      const j = window.jello;
      j.paused = true;
      j.device = device;
      j.loadCube(n);
      await j.settled();
      await j.runner.stepExactly(steps);
      return { positions: Array.from(j.sim.positions()), backend: j.sim.backend, time: j.sim.time, steps: j.sim.steps };
    },
    { n, device, steps },
  );
}

function largestGap(a, b) {
  assert.equal(a.length, b.length);
  return a.reduce((m, x, i) => Math.max(m, Math.abs(x - b[i])), 0);
}

describe('with WebGPU', () => {
  let browser;
  before(async () => {
    browser = await launch({ webgpu: true });
  });
  after(async () => {
    await browser?.close();
  });
  test('the GPU steps the cube, and the panel says so', async () => {
    const { page, done, showOverlays } = await open(browser);
    await page.waitForFunction(() => window.jello.sim.backend?.kind === 'webgpu', null, { timeout: 30_000 });
    const t0 = await page.evaluate(() => window.jello.sim.time);
    const a = await shot(page);
    await pause(1500);
    assert.ok((await page.evaluate(() => window.jello.sim.time)) > t0, 'simulated time advances');
    assert.ok((await difference(page, a, await shot(page))) > 100, 'the picture changes');
    await showOverlays();
    assert.match(await page.textContent('#backend'), /^WebGPU, f32 \(.+\)$/);
    // The adapter's name is long ("SwiftShader Device (Subzero)"): the row shows all of it.
    assert.deepEqual(await clippedLabels(page), []);
    assert.match(await page.textContent('#readout'), /on WebGPU/);
    await done();
  });

  test('200 steps on the GPU agree with the wasm core to 1e-4 m', async () => {
    const { page, done } = await open(browser);
    const gpu = await cubeAfter(page, 5, 'auto', 200);
    const cpu = await cubeAfter(page, 5, 'cpu', 200);
    assert.equal(gpu.backend.kind, 'webgpu');
    assert.equal(cpu.backend.kind, 'wasm');
    assert.equal(gpu.steps, 200);
    assert.equal(gpu.time, cpu.time, 'the time is summed as the core sums it');
    const gap = largestGap(gpu.positions, cpu.positions);
    const start = await cubeAfter(page, 5, 'cpu', 0);
    assert.ok(largestGap(start.positions, cpu.positions) > 1e-2, 'the cube fell');
    assert.ok(gap < 1e-4, `GPU and core differ by ${gap} m`);
    await done();
  });

  test('a model the GPU does not step falls back to the wasm core, and back', async () => {
    const { page, done } = await open(browser);
    await page.waitForFunction(() => window.jello.sim.backend?.kind === 'webgpu', null, { timeout: 30_000 });
    const implicit = await page.evaluate(async () => {
      const j = window.jello;
      j.setParameters({ ...j.parameters(), integrator: 'BackwardEuler', dt: 1 / 60 });
      await j.settled();
      return { backend: j.sim.backend, label: j.backendLabel };
    });
    assert.equal(implicit.backend.kind, 'wasm');
    assert.match(implicit.label, /^CPU, wasm f64: .*implicit integrator BackwardEuler/);
    const t0 = await page.evaluate(() => window.jello.sim.time);
    await pause(500);
    assert.ok((await page.evaluate(() => window.jello.sim.time)) > t0, 'the wasm core steps it');
    const back = await page.evaluate(async () => {
      const j = window.jello;
      j.setParameters({ ...j.parameters(), integrator: 'RK4', dt: 0.0005 });
      await j.settled();
      return j.sim.backend.kind;
    });
    assert.equal(back, 'webgpu');
    await done();
  });

  test('a push reaches the GPU, and a blow-up there stops at the last good step', async () => {
    const { page, done } = await open(browser);
    const rise = await page.evaluate(async () => {
      const j = window.jello;
      const meanZ = () => {
        const p = j.sim.positions();
        let z = 0;
        for (let i = 2; i < p.length; i += 3) z += p[i];
        return z / (p.length / 3);
      };
      j.paused = true;
      j.loadCube(4);
      await j.settled();
      const z0 = meanZ();
      j.sim.setPush(-1, 0, 0, 40); // 40 m/s² up, against 9.81 down
      await j.runner.stepExactly(100);
      return { backend: j.sim.backend.kind, rise: meanZ() - z0, time: j.sim.time };
    });
    assert.equal(rise.backend, 'webgpu');
    // Internal forces cancel: the centre rises at the net 40 - 9.81 m/s².
    const expected = 0.5 * (40 - 9.81) * rise.time ** 2;
    assert.ok(Math.abs(rise.rise - expected) < 1e-3 * expected + 1e-5, `the pushed cube rose ${rise.rise} m, not ${expected}`);

    const blown = await page.evaluate(async () => {
      const j = window.jello;
      j.sim.setPush(-1, 0, 0, 0);
      j.setParameters({ ...j.parameters(), dt: 0.05 });
      await j.settled();
      await j.runner.stepExactly(400);
      return { backend: j.sim.backend.kind, blownUp: j.sim.blownUp, message: j.sim.blowUpMessage(), steps: j.sim.steps, finite: j.sim.positions().every(Number.isFinite) };
    });
    assert.equal(blown.backend, 'webgpu');
    assert.ok(blown.blownUp, 'RK4 at dt = 0.05 s blows up');
    assert.match(blown.message, /step \d+/);
    assert.ok(blown.steps < 100 + 400, `stopped at step ${blown.steps}`);
    assert.ok(blown.finite, 'the state shown is the last good step');
    await page.waitForSelector('.banner-blowup', { state: 'attached' });
    await done();
  });

  test('pulls reach the GPU as the core takes them, and saving writes the GPU state', async () => {
    const { page, done } = await open(browser);
    const pulled = (device) =>
      page.evaluate(async (device) => {
        const j = window.jello;
        j.paused = true;
        j.device = device;
        j.loadCube(8);
        await j.settled();
        // The top corner and its neighbour, pulled up and sideways by damped springs.
        const p = j.sim.positions();
        const points = new Uint32Array([511, 510]);
        const targets = new Float64Array([...points].flatMap((i) => [p[3 * i] + 0.3, p[3 * i + 1], p[3 * i + 2] + 0.5]));
        j.sim.setPulls(points, targets, new Float64Array([2, 2]), new Float64Array([0.05, 0.05]));
        await j.runner.stepExactly(200);
        // How far the corner rose over the centre (which falls).
        const q = j.sim.positions();
        const meanZ = (a) => a.filter((_, k) => k % 3 === 2).reduce((s, z) => s + z, 0) / (a.length / 3);
        const rise = q[3 * 511 + 2] - meanZ(q) - (p[3 * 511 + 2] - meanZ(p));
        return { positions: Array.from(q), backend: j.sim.backend.kind, rise };
      }, device);
    const gpu = await pulled('auto');
    const cpu = await pulled('cpu');
    assert.equal(gpu.backend, 'webgpu');
    assert.ok(gpu.rise > 0.005, `the pulled corner rose ${gpu.rise} m over the centre`);
    const gap = largestGap(gpu.positions, cpu.positions);
    assert.ok(gap < 1e-4, `GPU and core differ by ${gap} m`);

    const saved = await page.evaluate(async () => {
      const j = window.jello;
      j.device = 'auto';
      j.loadCube(8);
      await j.settled();
      await j.runner.stepExactly(100);
      const before = Array.from(j.sim.positions());
      const { text, time } = await j.runner.save();
      j.paused = true;
      const loaded = j.loadText(text, 'saved.w');
      await j.settled();
      return { backend: j.sim.backend.kind, before, after: Array.from(j.sim.positions()), time, loaded };
    });
    assert.equal(saved.backend, 'webgpu');
    assert.ok(saved.loaded, 'the saved world loads');
    assert.ok(Math.abs(saved.time - 0.05) < 1e-12, `saved at t = ${saved.time}`);
    assert.deepEqual(saved.after, saved.before, 'the saved state is the GPU state shown');
    await done();
  });
});

describe('without WebGPU', () => {
  let browser;
  before(async () => {
    browser = await launch({ webgpu: false });
  });
  after(async () => {
    await browser?.close();
  });

  test('the wasm core steps, and the panel says why not the GPU', async () => {
    const { page, done, showOverlays } = await open(browser);
    await page.waitForFunction(() => window.jello.sim.backend !== undefined);
    assert.equal(await page.evaluate(() => window.jello.sim.backend.kind), 'wasm');
    await showOverlays();
    assert.equal(await page.textContent('#backend'), 'CPU, wasm f64: this browser has no WebGPU adapter');
    const t0 = await page.evaluate(() => window.jello.sim.time);
    await pause(500);
    assert.ok((await page.evaluate(() => window.jello.sim.time)) > t0 + 0.1, 'the wasm core keeps up');
    await done();
  });
});

/** A fresh viewer page in `browser`. */
function open(browser) {
  return openForTest(browser.context, server.url);
}
