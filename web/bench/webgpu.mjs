// Measures the viewer's two backends in headless Chromium with WebGPU on (README, "WebGPU"): the
// panel's n×n×n cube with RK4 at its own dt, stepped by exact requests to the stepping worker
// (`runner.stepExactly`; each reads the state back, as the running viewer does), on the GPU and
// on the wasm core in turn; then the classic world running at speed 1 on each. Without a GPU, Chromium's WebGPU adapter is SwiftShader, on the
// CPU: its figures are a floor, not a target.
// Usage: node bench/webgpu.mjs [SECONDS_PER_RUN]   (after scripts/web.sh and cargo build --release)
import { launch, openViewer } from '../tests/browser.mjs';
import { ROOT, startViewer } from '../tests/server.mjs';
import { join } from 'node:path';

const seconds = Number(process.argv[2] ?? 4);
const server = await startViewer([join(ROOT, 'examples', 'jello.w')]);
const browser = await launch({ webgpu: true });
try {
  const { page, errors } = await openViewer(browser.context, server.url);
  const adapter = await page.evaluate(() => window.jello.runner.webgpu);
  console.log(`WebGPU adapter: ${adapter ?? 'none'}`);

  /** Steps/s on `device` by exact requests, each of enough steps to take half a second (so the
   *  round trip to the worker is a small part), for about `seconds`. */
  const exact = (n, device) =>
    page.evaluate(
      async ({ n, device, seconds }) => {
        const j = window.jello;
        j.paused = true;
        j.device = device;
        j.loadCube(n);
        // On the CPU the viewer picks the implicit method above 8³: measure the cube's own RK4.
        if (j.parameters().integrator !== j.ownParameters.integrator) j.setParameters(j.ownParameters);
        await j.settled();
        let chunk = 1;
        for (;;) {
          const t = performance.now();
          await j.runner.stepExactly(chunk);
          if (performance.now() - t > 500 || chunk >= 1 << 16) break;
          chunk *= 2;
        }
        const t0 = performance.now();
        let steps = 0;
        while (performance.now() - t0 < seconds * 1000) steps += await j.runner.stepExactly(chunk);
        const b = j.sim.backend;
        return { rate: steps / ((performance.now() - t0) / 1000), backend: b.kind, kernel: b.kernel, dt: j.sim.dt, chunk };
      },
      { n, device, seconds },
    );

  console.log('| cube | dt (s) | WebGPU kernel | WebGPU steps/s | wasm steps/s | WebGPU / wasm |');
  console.log('| --- | ---: | --- | ---: | ---: | ---: |');
  for (const n of [8, 16, 24, 32]) {
    const gpu = await exact(n, 'auto');
    const cpu = await exact(n, 'cpu');
    if (gpu.backend !== 'webgpu' || cpu.backend !== 'wasm') throw new Error(`backends: ${gpu.backend}, ${cpu.backend}`);
    const ratio = gpu.rate / cpu.rate;
    console.log(`| ${n}³ | ${gpu.dt.toPrecision(3)} | ${gpu.kernel} | ${gpu.rate.toFixed(1)} | ${cpu.rate.toFixed(1)} | ${ratio.toFixed(2)}× |`);
  }

  console.log('\n| classic jello.w, running | real-time factor |');
  console.log('| --- | ---: |');
  for (const device of ['auto', 'cpu']) {
    const factor = await page.evaluate(
      async ({ device, seconds }) => {
        const j = window.jello;
        j.device = device;
        j.loadExample('jello.w');
        await new Promise((r) => setTimeout(r, 500));
        await j.settled();
        j.paused = false;
        await new Promise((r) => setTimeout(r, 2000));
        const [t0, s0] = [performance.now(), j.sim.time];
        await new Promise((r) => setTimeout(r, seconds * 1000));
        return (j.sim.time - s0) / ((performance.now() - t0) / 1000);
      },
      { device, seconds },
    );
    console.log(`| ${device === 'auto' ? 'WebGPU' : 'wasm'} | ${factor.toFixed(2)}× |`);
  }
  if (errors.length > 0) console.log('page errors:', errors);
} finally {
  await browser.close();
  await server.stop();
}
