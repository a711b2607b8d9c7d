// Scenes in the viewer, as a user meets them: `jello view` started on a scene file, the example
// scenes in the list, the home camera on a scene's own box, a colour for each of many bodies, a
// scene loaded by the picker and by drag and drop, skins lit and cages in wireframe, obstacles
// drawn, pulling and pushing one body of several, saving the state as a scene that loads again,
// and a bad scene's error. Run by scripts/web-test.sh after a build.
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import { join } from 'node:path';
import { after, before, describe, test } from 'node:test';
import { launch, openForTest } from './browser.mjs';
import { worldList } from './labels.mjs';
import { difference, shot } from './pixels.mjs';
import { JELLO, ROOT, startViewer } from './server.mjs';

const pause = (ms) => new Promise((r) => setTimeout(r, ms));

let server;
let browser;

before(async () => {
  server = await startViewer([join(ROOT, 'examples', 'stack.toml')]);
  browser = await launch();
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

const open = () => openForTest(browser.context, server.url);

const loaded = (page, name) =>
  page.waitForFunction((name) => document.getElementById('world-name')?.textContent === name, name);

/** Centre of body `b`'s active points now. */
const centre = (page, b) =>
  page.evaluate((b) => {
    const sim = window.jello.sim;
    const p = sim.positions();
    const bodies = sim.pointBodies();
    const active = sim.activePoints();
    const c = [0, 0, 0];
    let n = 0;
    for (let i = 0; i < bodies.length; i++) {
      if (bodies[i] !== b || !active[i]) continue;
      for (let a = 0; a < 3; a++) c[a] += p[3 * i + a];
      n++;
    }
    return c.map((x) => x / n);
  }, b);

/** Where point `i` is on the canvas (CSS pixels). */
const onCanvas = (page, i) =>
  page.evaluate((i) => {
    const app = window.jello;
    const p = app.sim.positions();
    const v = app.viewer.camera.position.clone().set(p[3 * i], p[3 * i + 1], p[3 * i + 2]).project(app.viewer.camera);
    return { x: ((v.x + 1) / 2) * app.viewer.canvas.clientWidth, y: ((1 - v.y) / 2) * app.viewer.canvas.clientHeight };
  }, i);

describe('scenes in the viewer', () => {
  test('jello view starts on a scene: three bodies and the sphere drawn, falling', async () => {
    const { page, done } = await open();
    assert.equal(await page.textContent('#world-name'), 'stack.toml');
    const sim = await page.evaluate(() => ({
      bodies: window.jello.sim.bodyNames(),
      scene: window.jello.sim.isScene,
      obstacles: Array.from(window.jello.sim.obstacles()),
    }));
    assert.deepEqual(sim.bodies, ['bottom', 'middle', 'top']);
    assert.ok(sim.scene);
    assert.equal(sim.obstacles[0], 1, 'a sphere');
    const a = await shot(page);
    await pause(600);
    assert.ok((await difference(page, a, await shot(page))) > 500, 'the bodies fall');
    await done();
  });

  test('the example scenes are listed and load, with their skins', async () => {
    const { page, done, showOverlays } = await open();
    await showOverlays();
    const names = await page.evaluate(() => window.jello.examples);
    for (const n of ['torus.toml', 'blob.toml', 'mould.toml', 'stack.toml', 'jello.w']) {
      assert.ok(names.includes(n), `${n} is listed: ${names}`);
    }
    // `jello view examples/stack.toml` shows that example, selected, not a copy as the user's own.
    const list = await worldList(page);
    assert.equal(list.selected, 'stack.toml');
    assert.ok(!list.options.some((o) => o.includes('your file')), `${list.options}`);
    await page.locator('#panel select:has(option:text-is("torus.toml"))').selectOption({ label: 'torus.toml' });
    await loaded(page, 'torus.toml');
    const counts = await page.evaluate(() => ({
      vertices: window.jello.sim.surfaceVertexCount,
      triangles: window.jello.sim.surfaceTriangles().length / 3,
    }));
    // `jello shape torus --detail 8`: 32 × 16 vertices.
    assert.deepEqual(counts, { vertices: 512, triangles: 1024 });
    await done();
  });

  test("the home camera frames each scene's box: the original's as the original did, another alike", async () => {
    const { page, done } = await open();
    /** Where the camera is and looks, and the world's box on the canvas: its centre and its
     *  corners' extent in normalised device coordinates. */
    const view = () =>
      page.evaluate(async () => {
        await new Promise(requestAnimationFrame);
        const { camera, controls } = window.jello.viewer;
        const [x0, y0, z0, x1, y1, z1] = window.jello.sim.copy.boundingBox();
        const ndc = (x, y, z) => camera.position.clone().set(x, y, z).project(camera);
        const corners = [];
        for (const x of [x0, x1]) for (const y of [y0, y1]) for (const z of [z0, z1]) corners.push(ndc(x, y, z));
        const xs = corners.map((c) => c.x);
        const ys = corners.map((c) => c.y);
        const centre = ndc((x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2);
        return {
          position: camera.position.toArray(),
          target: controls.target.toArray(),
          centre: [centre.x, centre.y],
          min: [Math.min(...xs), Math.min(...ys)],
          max: [Math.max(...xs), Math.max(...ys)],
        };
      });
    const near = (a, b, what) => a.forEach((x, i) => assert.ok(Math.abs(x - b[i]) < 1e-6, `${what}: ${a} against ${b}`));
    // stack.toml's box is the original's, 4 m a side about the origin: the original camera.
    const [c, s] = [Math.cos(Math.PI / 7), Math.sin(Math.PI / 7)];
    const original = await view();
    near(original.position, [11 * c * Math.cos(Math.PI / 5), 11 * c * Math.sin(Math.PI / 5), 11 * s], 'the original camera');
    near(original.target, [0, 0, 0], 'the original target');

    // pile.toml's box is 2 × 2 × 3.5 m from z = -1: centred, and as large on the canvas.
    await page.evaluate(() => window.jello.loadUrl('examples/pile.toml', 'pile.toml'));
    await loaded(page, 'pile.toml');
    const pile = await view();
    near(pile.target, [0, 0, 0.75], "the pile box's centre");
    for (const x of pile.centre) assert.ok(Math.abs(x) < 0.02, `the box is centred on the canvas: ${pile.centre}`);
    for (const x of [...pile.min, ...pile.max]) assert.ok(Math.abs(x) < 1, `the box is all on the canvas: ${pile.min} to ${pile.max}`);
    const height = (v) => v.max[1] - v.min[1];
    const ratio = height(pile) / height(original);
    assert.ok(ratio > 0.85 && ratio < 1.25, `the box as tall on the canvas as the original's: ${ratio.toFixed(2)} as tall`);

    // Zoomed and orbited, `e` brings it back; the original box again, the original camera.
    await page.keyboard.press('z');
    await page.keyboard.press('z');
    assert.ok(height(await view()) > 1.1 * height(pile), 'z zooms in');
    await page.keyboard.press('e');
    near((await view()).position, pile.position, 'e: the home camera of the pile');
    await page.evaluate(() => window.jello.loadUrl('examples/stack.toml', 'stack.toml'));
    await loaded(page, 'stack.toml');
    near((await view()).position, original.position, 'the original camera again');
    await done();
  });

  test('each body of a scene of many has a colour of its own, on every vertex of its skin', async () => {
    const { page, done } = await open();
    await page.keyboard.press('p');
    await page.evaluate(() => window.jello.loadUrl('examples/pile.toml', 'pile.toml'));
    await loaded(page, 'pile.toml');
    const { bodies, colours, mixed } = await page.evaluate(() => {
      const app = window.jello;
      const owner = app.sim.copy.surfaceBodies();
      const colour = app.viewer.surface.geometry.getAttribute('color');
      const byBody = new Map();
      let mixed = 0;
      owner.forEach((b, v) => {
        const c = [colour.getX(v), colour.getY(v), colour.getZ(v)].map((x) => Math.round(x * 255)).join(',');
        if (byBody.has(b) && byBody.get(b) !== c) mixed++;
        byBody.set(b, c);
      });
      return { bodies: app.sim.bodyNames().length, colours: new Set(byBody.values()).size, mixed };
    });
    assert.ok(bodies > 7, `more bodies than the palette has colours: ${bodies}`);
    assert.equal(mixed, 0, 'one colour a body');
    assert.equal(colours, bodies, 'as many colours as bodies');
    await done();
  });

  test("a scene the viewer steps implicitly keeps running: if the method stops, the file's own takes over", async () => {
    // mould.toml: 1042 points with friction, RK4 in its file; the viewer starts it with
    // BackwardEuler at 1/60 s.
    const { page, done } = await open();
    await page.evaluate(() => window.jello.loadUrl('examples/mould.toml', 'mould.toml'));
    await loaded(page, 'mould.toml');
    assert.equal((await page.evaluate(() => window.jello.parameters())).integrator, 'BackwardEuler');
    const t0 = await page.evaluate(() => window.jello.sim.time);
    await pause(3000);
    const after = await page.evaluate(() => ({
      time: window.jello.sim.time,
      blownUp: window.jello.sim.blownUp,
      integrator: window.jello.parameters().integrator,
      banner: document.querySelector('.banner-integrator')?.textContent ?? '',
    }));
    assert.equal(after.blownUp, false, 'not stopped');
    assert.equal(await page.locator('.banner-blowup').count(), 0);
    assert.ok(after.time > t0, 'time goes on');
    if (after.integrator !== 'BackwardEuler') {
      assert.equal(after.integrator, 'RK4');
      assert.match(after.banner, /BackwardEuler stopped .*the file's own RK4 at dt = [\d.e-]+ s carries on/);
    }
    await done();
  });

  test("the implicit banner counts a mesh body's points as `jello info` does, not its lattice's", async () => {
    // torus.toml and mould.toml are bodies voxelised from meshes: a whole lattice (845 and 1690
    // points) of which only the corners of kept cells take part.
    const { page, done } = await open();
    for (const name of ['torus.toml', 'mould.toml']) {
      const info = execFileSync(JELLO, ['info', join(ROOT, 'examples', name)], { encoding: 'utf8' });
      const counted = Number(info.match(/^body 1 .*?: (\d+) points \(lattice (\d+)×(\d+)×(\d+)\)/m)[1]);
      await page.evaluate((name) => window.jello.loadUrl(`examples/${name}`, name), name);
      await loaded(page, name);
      const shown = await page.evaluate(() => ({
        banner: document.querySelector('.banner-integrator')?.textContent ?? '',
        lattice: window.jello.sim.pointCount,
      }));
      assert.ok(counted < shown.lattice, `${name}: ${counted} active of ${shown.lattice}`);
      assert.match(shown.banner, new RegExp(`^${name} has ${counted} points: running BackwardEuler`));
    }
    await done();
  });

  test('a scene loads by the picker and by drag and drop; the wireframe shows the cage', async () => {
    const { page, done } = await open();
    await page.setInputFiles('#world-file', join(ROOT, 'examples', 'mould.toml'));
    await loaded(page, 'mould.toml');
    await page.keyboard.press('p');
    const lit = await shot(page);
    await page.keyboard.press('v');
    await pause(100);
    assert.ok((await difference(page, lit, await shot(page))) > 500, 'the cage differs from the skin');
    await page.keyboard.press('v');

    const text = readFileSync(join(ROOT, 'examples', 'blob.toml'), 'utf8');
    const drop = await page.evaluateHandle((text) => {
      const transfer = new DataTransfer();
      transfer.items.add(new File([text], 'blob.toml', { type: 'text/plain' }));
      return transfer;
    }, text);
    await page.dispatchEvent('body', 'drop', { dataTransfer: drop });
    await loaded(page, 'blob.toml');
    assert.equal(await page.locator('.banner-error').count(), 0);
    await done();
  });

  test('dragging a point of one body pulls that body, not the others', async () => {
    const { page, done } = await open();
    await page.keyboard.press('p');
    // Paused for good (a state the worker sent before the pause may still arrive), and drawn:
    // the point is found where the press will look for it.
    await page.evaluate(async () => {
      await window.jello.settled();
      await new Promise(requestAnimationFrame);
    });
    // The top cube's point nearest its centre: the ray through it meets the cube's skin well
    // inside its outline (a point on the outline, such as the corner nearest the camera, can be
    // missed by a ray grazing the silhouette, depending on where the pause left the cube).
    const grab = await page.evaluate(() => {
      const sim = window.jello.sim;
      const p = sim.positions();
      const bodies = sim.pointBodies();
      const top = [];
      for (let i = 0; i < bodies.length; i++) if (bodies[i] === 2) top.push(i);
      const c = [0, 1, 2].map((a) => top.reduce((s, i) => s + p[3 * i + a], 0) / top.length);
      let best = -1;
      let bestDistance = Infinity;
      for (const i of top) {
        const d = Math.hypot(p[3 * i] - c[0], p[3 * i + 1] - c[1], p[3 * i + 2] - c[2]);
        if (d < bestDistance) [best, bestDistance] = [i, d];
      }
      return best;
    });
    const at = await onCanvas(page, grab);
    const before = [await centre(page, 1), await centre(page, 2)];
    await page.mouse.move(at.x, at.y);
    await page.mouse.down();
    assert.ok(await page.evaluate(() => window.jello.interactionHandler.dragging), 'the press grabbed a point');
    await page.mouse.move(at.x, at.y - 150, { steps: 5 });
    await page.keyboard.press('p');
    await pause(1000);
    await page.keyboard.press('p');
    const after = [await centre(page, 1), await centre(page, 2)];
    await page.mouse.up();
    const rise = after[1][2] - before[1][2];
    const middle = after[0][2] - before[0][2];
    assert.ok(rise > 0.05, `the top cube rose (${rise.toFixed(3)} m)`);
    assert.ok(middle < rise / 2, `the middle cube did not follow (${middle.toFixed(3)} m)`);
    const pulls = await page.evaluate(() => window.jello.interactionHandler.dragging);
    assert.equal(pulls, false);
    await done();
  });

  test('right-dragging a body pushes it alone', async () => {
    const { page, done } = await open();
    await page.keyboard.press('p');
    // Paused for good and drawn, as in the test above.
    await page.evaluate(async () => {
      await window.jello.settled();
      await new Promise(requestAnimationFrame);
    });
    const right = await page.evaluate(() => {
      const m = window.jello.viewer.camera.matrixWorld.elements;
      return [m[0], m[1], m[2]];
    });
    const at = await page.evaluate(() => {
      // The middle cube's centre point (2, 2, 2) of its 5×5×5 lattice, on the canvas.
      const app = window.jello;
      const p = app.sim.positions();
      const i = 125 + (2 * 5 + 2) * 5 + 2;
      const v = app.viewer.camera.position.clone().set(p[3 * i], p[3 * i + 1], p[3 * i + 2]).project(app.viewer.camera);
      return { x: ((v.x + 1) / 2) * app.viewer.canvas.clientWidth, y: ((1 - v.y) / 2) * app.viewer.canvas.clientHeight };
    });
    const before = [await centre(page, 1), await centre(page, 2)];
    await page.mouse.move(at.x, at.y);
    await page.mouse.down({ button: 'right' });
    const pushed = await page.evaluate(() => window.jello.interactionHandler.active?.body);
    assert.equal(pushed, 1, 'the press picked the middle cube');
    await page.mouse.move(at.x + 300, at.y, { steps: 4 });
    // Single steps while paused, so that the push lasts the same simulated time on any
    // machine: 80 steps of 1 ms. (Run for half a second of wall clock, it lasted as long as the
    // frames allowed, the top cube was dragged along by friction at up to μ·g all the while,
    // and the test failed on about half the runs on a quiet machine.)
    for (let k = 0; k < 80; k++) await page.keyboard.press('n');
    // The worker takes the steps after the key presses return: the push is held, and the
    // positions read, only once it has taken them all (once, it had not, and the cube had
    // moved 0 m).
    await page.evaluate(() => window.jello.settled());
    await page.mouse.up({ button: 'right' });
    const after = [await centre(page, 1), await centre(page, 2)];
    const along = (b) => [0, 1, 2].reduce((s, a) => s + (after[b][a] - before[b][a]) * right[a], 0);
    assert.ok(along(0) > 0.01, `the middle cube moved right (${along(0).toFixed(3)} m)`);
    assert.ok(Math.abs(along(1)) < along(0) / 2, `the top cube moved less (${along(1).toFixed(3)} m)`);
    await done();
  });

  test('save writes the scene with its state, which loads again', async () => {
    const { page, done } = await open();
    await pause(300);
    await page.keyboard.press('p');
    const download = page.waitForEvent('download');
    await page.evaluate(() => window.jello.save());
    const file = await download;
    assert.match(file.suggestedFilename(), /^stack-t\d+\.\d{3}\.toml$/);
    const text = readFileSync(await file.path(), 'utf8');
    assert.match(text, /\[body\.state\]/);
    const same = await page.evaluate((text) => {
      const before = window.jello.sim.positions();
      const ok = window.jello.loadText(text, 'saved.toml');
      const after = window.jello.sim.positions();
      return ok && before.every((x, i) => x === after[i]);
    }, text);
    assert.ok(same, 'the saved scene loads with the same positions');
    await done();
  });

  test('the tolerance row sets how closely implicit steps are solved, and a saved scene keeps it', async () => {
    const { page, done, showOverlays } = await open();
    await showOverlays();
    await page.keyboard.press('p');
    const integrator = page.locator('#panel select:has(option:text-is("BackwardEuler"))');
    const tolerance = page.locator('#panel select:has(option:text-is("1e-3 (fastest)"))');
    // RK4 has no tolerance to set.
    assert.equal(await tolerance.isDisabled(), true);
    await integrator.selectOption({ label: 'BackwardEuler' });
    assert.equal(await tolerance.isDisabled(), false);
    await tolerance.selectOption({ label: '1e-5' });
    assert.equal((await page.evaluate(() => window.jello.parameters())).tolerance, 1e-5);
    // The worker steps with it: a few steps, then its state saved as a scene carries it.
    await page.evaluate(() => window.jello.runner.stepExactly(3));
    const download = page.waitForEvent('download');
    await page.evaluate(() => window.jello.save());
    const text = readFileSync(await (await download).path(), 'utf8');
    assert.match(text, /^integrator = "BackwardEuler"$/m);
    assert.match(text, /^tolerance = (1e-5|0\.00001)$/m);
    // A value out of range is refused with the core's reason, and nothing changes.
    const message = await page.evaluate(() => window.jello.setParameters({ ...window.jello.parameters(), tolerance: 0.5 }));
    assert.match(message, /tolerance must be at most 0\.1/);
    assert.equal((await page.evaluate(() => window.jello.parameters())).tolerance, 1e-5);
    await done();
  });

  test('a bad scene shows its file, line and column, and the running scene goes on', async () => {
    const { page, done } = await open();
    await page.setInputFiles('#world-file', {
      name: 'broken.toml',
      mimeType: 'text/plain',
      buffer: Buffer.from('[simulation]\ndt = 0.001\ncolour = "red"\n'),
    });
    const banner = page.locator('.banner-error');
    await banner.waitFor({ state: 'attached' });
    const text = await banner.textContent();
    assert.match(text, /broken\.toml:3:1: .*colour/, `the error names the file, line and column: ${text}`);
    assert.equal(await page.textContent('#world-name'), 'stack.toml');
    await done();
  });
});
