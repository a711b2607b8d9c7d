// Shared by the Playwright tests and the measurement script: Debian's Chromium, headless, driven
// by playwright-core (never `playwright install`).
import assert from 'node:assert/strict';
import { mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromium } from 'playwright-core';
import { hideOverlays } from './pixels.mjs';

export const CHROMIUM = process.env.CHROMIUM ?? '/usr/bin/chromium';

/** Launches Chromium with a fresh profile; `close()` stops it and removes the profile. With
 *  `webgpu`, the page has WebGPU (SwiftShader, on the CPU: `--enable-unsafe-webgpu`); without it
 *  the GPU is off and `navigator.gpu` finds no adapter, so the viewer steps on the wasm core. */
export async function launch({ webgpu = false } = {}) {
  const profile = mkdtempSync(join(tmpdir(), 'jello-chromium-'));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: CHROMIUM,
    headless: true,
    acceptDownloads: true,
    viewport: { width: 960, height: 640 },
    args: [
      '--headless',
      '--no-sandbox',
      ...(webgpu ? ['--enable-unsafe-webgpu'] : ['--disable-gpu']),
      '--disable-quic',
      '--no-first-run',
      '--disable-background-networking',
      '--disable-component-update',
      '--disable-sync',
      // Keep requestAnimationFrame running at full rate in a page nobody looks at.
      '--disable-background-timer-throttling',
      '--disable-renderer-backgrounding',
      '--disable-backgrounding-occluded-windows',
    ],
  });
  return {
    context,
    async close() {
      await context.close();
      rmSync(profile, { recursive: true, force: true });
    },
  };
}

/** Opens the viewer at `url` and waits until it runs; collects page errors and console errors. */
export async function openViewer(context, url) {
  const page = await context.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(`pageerror: ${e.message}`));
  page.on('console', (m) => {
    if (m.type() === 'error') errors.push(`console: ${m.text()}`);
  });
  await page.goto(url);
  await page.waitForSelector('body[data-ready="true"]', { timeout: 30_000 });
  return { page, errors };
}

/** For a test: a fresh page on the viewer at `url` with the overlays hidden (`showOverlays()`
 *  brings them back); `done()` closes it and asserts that it reported no page or console errors. */
export async function openForTest(context, url) {
  const { page, errors } = await openViewer(context, url);
  const showOverlays = await hideOverlays(page);
  await new Promise((r) => setTimeout(r, 300));
  return {
    page,
    errors,
    showOverlays,
    async done() {
      await page.close();
      assert.deepEqual(errors, [], 'the page reported errors');
    },
  };
}
