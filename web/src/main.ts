// Entry point: load the core, ask the server what to show, start the app.
import './style.css';
import { App, errorMessage } from './app';
import { bindKeys, KEYS } from './keys';
import { exampleUrl, listedUrl, type ServerConfig } from './served';
import { JelloSim, Runner, loadCore, type Source } from './sim';

/** `config.json` from `jello view`; without it (a plain static server, `vite dev`) no examples
 *  and the classic cube. */
async function serverConfig(): Promise<ServerConfig> {
  try {
    const r = await fetch('config.json');
    if (r.ok && r.headers.get('content-type')?.includes('json')) return (await r.json()) as ServerConfig;
  } catch {
    // No server config: fall through.
  }
  return { examples: [] };
}

/** The world to start with: the one given to `jello view`, else the classic example, else the
 *  classic cube at rest under gravity; `listedAs` is its URL in the panel's list. */
async function firstWorld(
  config: ServerConfig,
): Promise<{ sim: JelloSim; source: Source; listedAs?: string; error?: string }> {
  const classic = exampleUrl('jello.w');
  const candidates = [
    config.world && { ...config.world, listedAs: listedUrl(config.world, config) },
    config.examples.includes('jello.w') ? { url: classic, name: 'jello.w', listedAs: classic } : undefined,
  ];
  let error: string | undefined;
  for (const c of candidates) {
    if (!c) continue;
    try {
      const r = await fetch(c.url);
      if (!r.ok) throw new Error(`${r.status} ${r.statusText}`);
      const text = await r.text();
      const sim = JelloSim.load(text, c.name);
      return { sim, source: { kind: 'text', text, name: c.name }, listedAs: c.listedAs, error };
    } catch (e) {
      error = `Could not load ${c.name}: ${errorMessage(e)}`;
    }
  }
  return { sim: JelloSim.cube(8), source: { kind: 'cube', n: 8 }, error };
}

function fillHelp(): void {
  const list = document.getElementById('help-keys');
  if (!list) return;
  for (const [key, what] of KEYS) {
    const dt = document.createElement('dt');
    dt.textContent = key;
    const dd = document.createElement('dd');
    dd.textContent = what;
    list.append(dt, dd);
  }
}

async function main(): Promise<void> {
  fillHelp();
  await loadCore();
  const config = await serverConfig();
  const { sim, source, listedAs, error } = await firstWorld(config);
  const runner = await Runner.start(sim, source);
  const canvas = document.getElementById('view') as HTMLCanvasElement;
  const app = new App(canvas, runner, config, listedAs);
  bindKeys(app);
  if (error) app.banners.show('error', error);
  // A handle for the console and the tests: `jello.sim.time`, `jello.paused`, …
  (window as unknown as { jello: App }).jello = app;
  document.body.dataset.ready = 'true';
}

main().catch((e: unknown) => {
  const el = document.getElementById('banners');
  if (el) el.textContent = `Jello could not start: ${errorMessage(e)}`;
  throw e;
});
