// The viewer as a user sees it: `jello view` serving the built page to headless Chromium, checked
// by the pixels it draws. Run by scripts/web-test.sh (part of `make test`) or `npm test` after a
// build.
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { after, before, describe, test } from 'node:test';
import { launch, openForTest } from './browser.mjs';
import { analyse, difference, shot } from './pixels.mjs';
import { JELLO, ROOT, startViewer } from './server.mjs';

const pause = (ms) => new Promise((r) => setTimeout(r, ms));

let server;
let browser;

before(async () => {
  server = await startViewer([join(ROOT, 'examples', 'jello.w')]);
  browser = await launch();
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

const open = () => openForTest(browser.context, server.url);

const simTime = (page) => page.evaluate(() => window.jello.sim.time);

describe('jello view', () => {
  test('serves on 127.0.0.1 and says so', () => {
    assert.match(server.url, /^http:\/\/127\.0\.0\.1:\d+\/$/);
    assert.match(server.output(), /showing jello\.w/);
  });

  test('the canvas shows the lit jello, the box and the plane', async () => {
    const { page, done } = await open();
    const a = await analyse(page, await shot(page));
    assert.ok(a.red > 500, `expected the red jello on the canvas, found ${a.red} red pixels`);
    assert.ok(a.drawn > a.red + 2000, `expected the box and plane too (${a.drawn} drawn pixels)`);
    assert.equal(await page.textContent('#world-name'), 'jello.w');
    await done();
  });

  test('the cube moves', async () => {
    const { page, done } = await open();
    const t0 = await simTime(page);
    const a = await shot(page);
    await pause(1000);
    const b = await shot(page);
    assert.ok((await simTime(page)) > t0 + 0.3, 'simulated time advances with the wall clock');
    const changed = await difference(page, a, b);
    assert.ok(changed > 300, `expected the picture to change, ${changed} pixels did`);
    await done();
  });

  test('p freezes the picture, v changes it while paused, p resumes', async () => {
    const { page, done } = await open();
    await page.keyboard.press('p');
    await pause(300);
    const a = await shot(page);
    await pause(800);
    const b = await shot(page);
    assert.equal(await difference(page, a, b), 0, 'paused: two screenshots are equal');

    await page.keyboard.press('v');
    await pause(300);
    const c = await shot(page);
    const wire = await analyse(page, c, b);
    assert.ok(wire.differing > 500, `v changes the picture (${wire.differing} pixels)`);
    assert.ok(wire.red < 100, `wireframe shows no lit surface (${wire.red} red pixels)`);
    await pause(500);
    assert.equal(await difference(page, c, await shot(page)), 0, 'still frozen after v');

    await page.keyboard.press('p');
    await pause(1000);
    assert.ok((await difference(page, c, await shot(page))) > 100, 'p resumes');
    await done();
  });

  test('s, h and b toggle spring kinds in the wireframe', async () => {
    const { page, done } = await open();
    await page.keyboard.press('p');
    await page.keyboard.press('v');
    await pause(300);
    let before = await shot(page);
    for (const key of ['s', 'h', 'b']) {
      await page.keyboard.press(key);
      await pause(250);
      const now = await shot(page);
      assert.ok((await difference(page, before, now)) > 50, `${key} changes the wireframe`);
      before = now;
    }
    // All three off: only the surface points remain, a sparse picture.
    assert.deepEqual(await page.evaluate(() => window.jello.showKind), [false, false, false]);
    await done();
  });

  test('n single-steps while paused; e resets the camera after zooming', async () => {
    const { page, done } = await open();
    await page.keyboard.press('p');
    // The worker may be mid-slice when the pause arrives: wait until it has answered.
    await page.evaluate(() => window.jello.settled());
    const steps = await page.evaluate(() => window.jello.sim.steps);
    await page.keyboard.press('n');
    await page.evaluate(() => window.jello.settled());
    assert.equal(await page.evaluate(() => window.jello.sim.steps), steps + 1);
    await pause(200);
    const home = await shot(page);
    await page.keyboard.press('z');
    await page.keyboard.press('z');
    await pause(250);
    const zoomed = await shot(page);
    assert.ok((await difference(page, home, zoomed)) > 500, 'z zooms');
    await page.keyboard.press('e');
    await pause(250);
    assert.equal(await difference(page, home, await shot(page)), 0, 'e goes back to the home view');
    await done();
  });

  test('loading a world from a file works', async () => {
    const { page, done } = await open();
    const before = await shot(page);
    await page.setInputFiles('#world-file', join(ROOT, 'examples', 'rotate.w'));
    await page.waitForFunction(() => document.getElementById('world-name')?.textContent === 'rotate.w');
    assert.equal(await page.evaluate(() => window.jello.sim.dt), 0.001);
    await pause(500);
    assert.ok((await difference(page, before, await shot(page))) > 500, 'the new world is drawn');
    assert.equal(await page.locator('.banner-error').count(), 0);
    await done();
  });

  test('an example from the list loads', async () => {
    const { page, done, showOverlays } = await open();
    await showOverlays();
    const names = await page.evaluate(() => window.jello.examples);
    assert.ok(names.includes('spin.w') && names.includes('jello.w'), `examples listed: ${names}`);
    await page.locator('#panel select:has(option:text-is("spin.w"))').selectOption({ label: 'spin.w' });
    await page.waitForFunction(() => document.getElementById('world-name')?.textContent === 'spin.w');
    await done();
  });

  test('a bad file shows its error and the running world goes on', async () => {
    const { page, done } = await open();
    await page.setInputFiles('#world-file', {
      name: 'broken.w',
      mimeType: 'text/plain',
      buffer: Buffer.from('RK4\n0.0005 1\n200 0.25 400 0.25\n0.001953125\n0\n0\n0.5 0.5 oops\n'),
    });
    const banner = page.locator('.banner-error');
    await banner.waitFor({ state: 'attached' });
    const text = await banner.textContent();
    assert.match(text, /broken\.w:7:/, `the error names the file and line: ${text}`);
    assert.equal(await page.textContent('#world-name'), 'jello.w');
    const t0 = await simTime(page);
    const a = await shot(page);
    await pause(800);
    assert.ok((await simTime(page)) > t0, 'the simulation keeps running');
    assert.ok((await difference(page, a, await shot(page))) > 100, 'and the picture keeps moving');
    await done();
  });

  test('a blow-up keeps the last good frame, says what happened and suggests a dt', async () => {
    const { page, done, showOverlays } = await open();
    await page.evaluate(() => window.jello.setParameters({ ...window.jello.parameters(), dt: 0.02 }));
    await page.waitForFunction(() => window.jello.sim.blownUp);
    const banner = page.locator('.banner-blowup');
    await banner.waitFor({ state: 'attached' });
    assert.match(await banner.textContent(), /blew up at step \d+.*try dt = [\d.e-]+ s/);
    const a = await shot(page);
    await pause(500);
    assert.equal(await difference(page, a, await shot(page)), 0, 'the picture stays on the last good frame');
    const positionsFinite = await page.evaluate(() => window.jello.sim.positions().every(Number.isFinite));
    assert.ok(positionsFinite);
    await showOverlays();
    await banner.getByRole('button', { name: /Use dt/ }).click();
    await page.waitForFunction(() => !window.jello.sim.blownUp && window.jello.sim.time > 0.1);
    assert.equal(await page.locator('.banner-blowup').count(), 0);
    await done();
  });

  test('the simulation steps in a worker: time goes on while the page is busy', async () => {
    const { page, done } = await open();
    // Block the page's own thread for 1.5 s: no frame is drawn, yet the worker keeps stepping,
    // and the first state the page sees after is well on. (Stepping on the page's thread would
    // have advanced nothing; how near it gets to 1.5 s depends on the CPU the worker is left,
    // which a test does not assert: on a loaded 2-core machine it reached 1.05 s.)
    const { before, after } = await page.evaluate(() => {
      const app = window.jello;
      const before = app.sim.time;
      const until = performance.now() + 1500;
      while (performance.now() < until) {
        // busy
      }
      return new Promise((resolve) =>
        setTimeout(() => app.settled().then(() => resolve({ before, after: app.sim.time })), 50),
      );
    });
    assert.ok(after - before > 0.5, `simulated time advanced ${(after - before).toFixed(3)} s while the page was blocked for 1.5 s`);
    await done();
  });

  test('a cube larger than 8³ starts with the implicit integrator at dt = 1/60 s', async () => {
    const { page, done, showOverlays } = await open();
    await page.evaluate(() => window.jello.loadCube(12));
    const p = await page.evaluate(() => window.jello.parameters());
    assert.equal(p.integrator, 'BackwardEuler');
    assert.ok(Math.abs(p.dt - 1 / 60) < 1e-12, `dt ${p.dt}`);
    assert.equal(p.tolerance, 1e-5);
    const banner = page.locator('.banner-integrator');
    assert.match(await banner.textContent(), /1728 points: running BackwardEuler at dt = 1\/60 s \(tolerance 1e-5 m\/s\)/);
    // It runs (how fast is for web/bench/measure.mjs, not a test).
    const t0 = await simTime(page);
    await page.waitForFunction((t0) => window.jello.sim.time > t0 + 0.1, t0);
    assert.equal(await page.evaluate(() => window.jello.sim.blownUp), false);
    // The readout says how many Newton iterations a step takes: none while the cube falls
    // freely (Newton's first iterate, the momentum shift, is then the solution), some once it
    // lands on the floor, 2 m below.
    await page.waitForFunction(() =>
      /\d\.\d Newton iterations a step$/.test(document.getElementById('readout')?.textContent ?? ''),
    );
    await page.waitForFunction(() => window.jello.sim.newtonIterations > 0);
    // A reset keeps the choice; the banner's button goes back to the cube's own.
    await page.evaluate(() => window.jello.reset());
    assert.equal((await page.evaluate(() => window.jello.parameters())).integrator, 'BackwardEuler');
    await showOverlays();
    await banner.getByRole('button', { name: /Use RK4/ }).click();
    const own = await page.evaluate(() => window.jello.parameters());
    assert.deepEqual([own.integrator, own.tolerance], ['RK4', 1e-9]);
    // An explicit integrator's readout has no Newton iterations.
    await page.waitForFunction(() => /step \d+ · running$/.test(document.getElementById('readout')?.textContent ?? ''));
    // The classic cube keeps its own integrator.
    await page.evaluate(() => window.jello.loadCube(8));
    assert.equal((await page.evaluate(() => window.jello.parameters())).integrator, 'RK4');
    await done();
  });

  test('a screenshot downloads as PNG', async () => {
    const { page, done } = await open();
    const download = page.waitForEvent('download');
    await page.evaluate(() => window.jello.screenshot());
    const file = await download;
    assert.equal(file.suggestedFilename(), 'jello.png');
    const png = readFileSync(await file.path());
    assert.deepEqual([...png.subarray(1, 4)], [...Buffer.from('PNG')]);
    const a = await analyse(page, png);
    assert.ok(a.red > 500, `the screenshot shows the jello (${a.red} red pixels)`);
    await done();
  });

  test('space records a frame sequence, downloaded as a zip of numbered PNGs', async () => {
    const { page, done } = await open();
    await page.keyboard.press(' ');
    const t0 = await simTime(page);
    await page.waitForFunction((t0) => window.jello.sim.time > t0 + 0.5, t0);
    const download = page.waitForEvent('download');
    await page.keyboard.press(' ');
    const t1 = await simTime(page);
    const file = await download;
    assert.equal(file.suggestedFilename(), 'jello-frames.zip');
    const zip = readFileSync(await file.path());
    // Each name appears in a local header and in the central directory.
    const names = [...new Set([...zip.toString('latin1').matchAll(/(\d{3})\.png/g)].map((m) => m[1]))];
    assert.ok(names.includes('000') && names.includes('001') && names.includes('005'), `frames: ${names}`);
    assert.deepEqual(names, names.map((_, i) => String(i).padStart(3, '0')), 'numbered from 000 without gaps');
    // 15 frames per simulated second.
    assert.ok(Math.abs(names.length - (t1 - t0) * 15) <= 2, `${names.length} frames for ${(t1 - t0).toFixed(2)} s`);
    await done();
  });

  test('save writes the current state as a world file that loads again', async () => {
    const { page, done } = await open();
    await page.keyboard.press('p');
    const download = page.waitForEvent('download');
    await page.evaluate(() => window.jello.save());
    const file = await download;
    assert.match(file.suggestedFilename(), /^jello-t\d+\.\d{3}\.w$/);
    const text = readFileSync(await file.path(), 'utf8');
    assert.match(text, /^RK4\n0.0005 1\n/);
    const ok = await page.evaluate((t) => window.jello.loadText(t, 'saved.w'), text);
    assert.ok(ok);
    await done();
  });

  /** Loads the classic cube at rest, centred, with no field or plane (made by `jello create`). */
  async function restingCube(page) {
    const file = join(mkdtempSync(join(tmpdir(), 'jello-test-')), 'rest.w');
    execFileSync(JELLO, ['create', file, '--offset=-0.5,-0.5,-0.5']);
    await page.setInputFiles('#world-file', file);
    await page.waitForFunction(() => document.getElementById('world-name')?.textContent === 'rest.w');
  }

  /** Centre of mass, and the position of point `i`, of the current state. */
  const where = (page, i) =>
    page.evaluate((i) => {
      const p = window.jello.sim.positions();
      const n = p.length / 3;
      const c = [0, 1, 2].map((a) => p.filter((_, k) => k % 3 === a).reduce((s, v) => s + v, 0) / n);
      return { centre: c, point: [p[3 * i], p[3 * i + 1], p[3 * i + 2]] };
    }, i);

  test('dragging a point of the jello pulls it toward the pointer', async () => {
    const { page, done } = await open();
    await restingCube(page);
    const corner = 511; // (7, 7, 7), the corner facing the camera
    const at = await page.evaluate((i) => {
      const app = window.jello;
      const p = app.sim.positions();
      const v = app.viewer.camera.position.clone().set(p[3 * i], p[3 * i + 1], p[3 * i + 2]).project(app.viewer.camera);
      return { x: ((v.x + 1) / 2) * app.viewer.canvas.clientWidth, y: ((1 - v.y) / 2) * app.viewer.canvas.clientHeight };
    }, corner);
    const before = await where(page, corner);
    await page.mouse.move(at.x - 2, at.y + 2);
    await page.mouse.down();
    await page.mouse.move(at.x - 2, at.y - 150, { steps: 5 });
    await pause(1200);
    assert.ok(await page.evaluate(() => window.jello.interactionHandler.dragging), 'the press grabbed a point');
    const pulled = await where(page, corner);
    await page.mouse.up();
    assert.equal(await page.evaluate(() => window.jello.interactionHandler.dragging), false);
    const rise = pulled.point[2] - before.point[2];
    const centreRise = pulled.centre[2] - before.centre[2];
    assert.ok(rise > 0.1, `the grabbed corner rose (${rise.toFixed(3)} m)`);
    assert.ok(rise > centreRise, 'more than the cube as a whole: the jello deforms');
    await done();
  });

  test('dragging in empty space pushes the whole cube', async () => {
    const { page, done } = await open();
    await restingCube(page);
    const right = await page.evaluate(() => {
      const m = window.jello.viewer.camera.matrixWorld.elements;
      return [m[0], m[1], m[2]];
    });
    const before = await where(page, 0);
    // Right-drag from an empty corner of the canvas toward the right.
    await page.mouse.move(60, 560);
    await page.mouse.down({ button: 'right' });
    await page.mouse.move(260, 560, { steps: 5 });
    await pause(600);
    await page.mouse.up({ button: 'right' });
    const after = await where(page, 0);
    const moved = [0, 1, 2].reduce((s, a) => s + (after.centre[a] - before.centre[a]) * right[a], 0);
    assert.ok(moved > 0.1, `the cube moved ${moved.toFixed(3)} m to the camera's right`);
    await done();
  });
});
