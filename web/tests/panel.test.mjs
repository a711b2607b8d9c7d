// The panel as a user reads it: every label whole at a desktop's, a small window's and a
// phone's width, and the list of worlds when `jello view` serves a user's own file: that file
// named as theirs and selected, above the examples; a file opened or a cube built here named
// too, so the list is never blank. Run by scripts/web-test.sh after a build.
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { copyFileSync, mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { after, before, describe, test } from 'node:test';
import { launch, openForTest } from './browser.mjs';
import { clippedLabels, worldList } from './labels.mjs';
import { JELLO, ROOT, startViewer } from './server.mjs';

const SIZES = [
  [1280, 800],
  [800, 600],
  [420, 700],
];

let folder;
let browser;
let ownScene;
let ownJello;

before(async () => {
  folder = mkdtempSync(join(tmpdir(), 'jello-panel-'));
  // A user's own scene, and a user's own world that happens to share an example's name.
  const mine = join(folder, 'mine.toml');
  execFileSync(JELLO, ['create', mine, '--cube', '5', '--size', '0.5', '--at', '0,0,0']);
  copyFileSync(join(ROOT, 'examples', 'rotate.w'), join(folder, 'jello.w'));
  ownScene = await startViewer([mine]);
  ownJello = await startViewer([join(folder, 'jello.w')]);
  browser = await launch();
});

after(async () => {
  await browser?.close();
  await ownScene?.stop();
  await ownJello?.stop();
  rmSync(folder, { recursive: true, force: true });
});

/** A fresh page on `server` with the panel showing. */
async function open(server) {
  const opened = await openForTest(browser.context, server.url);
  await opened.showOverlays();
  return opened;
}

const loaded = (page, name) =>
  page.waitForFunction((name) => document.getElementById('world-name')?.textContent === name, name);

describe('the panel', () => {
  for (const [width, height] of SIZES) {
    test(`at ${width}×${height} every label, choice and text reads whole`, async () => {
      const { page, done } = await open(ownScene);
      await page.setViewportSize({ width, height });
      await page.waitForFunction(() => window.jello.sim.backend !== undefined);
      await new Promise((r) => setTimeout(r, 100)); // the panel follows within a frame
      assert.deepEqual(await clippedLabels(page), []);
      // The world's name and the readout stay clear of the panel: wrapped, not hidden under it.
      const overlap = await page.evaluate(() => {
        const panel = document.querySelector('#panel .lil-root').getBoundingClientRect();
        return Array.from(document.querySelectorAll('#hud > span'), (e) => e.getBoundingClientRect().right - panel.left);
      });
      assert.ok(overlap.every((o) => o <= 0), `the top left's text runs under the panel by ${overlap} px`);
      // The backend row says all of why the GPU does not step, not its first words.
      assert.equal(await page.textContent('#backend'), 'CPU, wasm f64: this browser has no WebGPU adapter');
      await done();
    });
  }

  test("a user's scene is listed as theirs and selected, above the examples", async () => {
    const { page, done } = await open(ownScene);
    const list = await worldList(page);
    assert.equal(list.options[0], 'mine.toml (your file)');
    for (const n of ['jello.w', 'spin.w', 'stack.toml']) assert.ok(list.options.includes(n), `${n} is listed: ${list.options}`);
    assert.equal(list.selected, 'mine.toml (your file)');
    assert.equal(list.shown, 'mine.toml (your file)');

    // An example, then the user's file again, from the list.
    await page.locator('#worlds select').selectOption({ label: 'spin.w' });
    await loaded(page, 'spin.w');
    assert.equal((await worldList(page)).selected, 'spin.w');
    await page.locator('#worlds select').selectOption({ label: 'mine.toml (your file)' });
    await loaded(page, 'mine.toml');
    assert.equal((await worldList(page)).selected, 'mine.toml (your file)');
    assert.equal(await page.evaluate(() => window.jello.sim.isScene), true);
    await done();
  });

  test('a file opened here or a cube built here is named in the list, which is never blank', async () => {
    const { page, done } = await open(ownScene);
    await page.setInputFiles('#world-file', join(ROOT, 'examples', 'rotate.w'));
    await loaded(page, 'rotate.w');
    assert.deepEqual(
      { ...(await worldList(page)), options: undefined },
      { options: undefined, selected: undefined, shown: 'rotate.w (opened here)' },
    );
    await page.evaluate(() => window.jello.loadCube(6));
    await loaded(page, 'cube 6³');
    assert.equal((await worldList(page)).shown, 'cube 6³ (built here)');
    await done();
  });

  test('a listed world that cannot be fetched: the list goes back to the world still running', async () => {
    const { page, errors, done } = await open(ownScene);
    await page.route('**/examples/spin.w', (route) => route.fulfill({ status: 404, body: 'gone' }));
    await page.locator('#worlds select').selectOption({ label: 'spin.w' });
    await page.waitForSelector('.banner-error:has-text("Could not fetch spin.w")');
    assert.equal(await page.textContent('#world-name'), 'mine.toml');
    assert.equal((await worldList(page)).selected, 'mine.toml (your file)');
    // The browser's own report of the 404 is expected here.
    const expected = errors.filter((e) => /status of 404/.test(e));
    assert.equal(expected.length, 1, `${errors}`);
    errors.splice(errors.indexOf(expected[0]), 1);
    await done();
  });

  test("a user's file with an example's name is listed as theirs, beside the example", async () => {
    const { page, done } = await open(ownJello);
    const list = await worldList(page);
    assert.equal(list.options[0], 'jello.w (your file)');
    assert.ok(list.options.includes('jello.w'), `the example is listed too: ${list.options}`);
    assert.equal(list.selected, 'jello.w (your file)');
    assert.equal(await page.evaluate(() => window.jello.sim.dt), 0.001, "rotate.w's step: the user's file runs");

    await page.locator('#worlds select').selectOption({ label: 'jello.w' });
    await page.waitForFunction(() => window.jello.sim.dt === 0.0005);
    assert.equal((await worldList(page)).selected, 'jello.w');
    await done();
  });
});
