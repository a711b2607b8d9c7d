// Starts `jello view` on a free port of 127.0.0.1 for the tests, and stops it.
import { spawn } from 'node:child_process';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

export const ROOT = join(dirname(fileURLToPath(import.meta.url)), '..', '..');
export const JELLO = process.env.JELLO_BIN ?? join(ROOT, 'target', 'release', 'jello');

/** Runs `jello view ARGS --port 0` and resolves once it prints its URL. */
export function startViewer(args = []) {
  const child = spawn(JELLO, ['view', ...args, '--port', '0'], { stdio: ['ignore', 'pipe', 'pipe'] });
  let output = '';
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => fail(new Error(`jello view printed no URL in 20 s:\n${output}`)), 20_000);
    const fail = (e) => {
      clearTimeout(timer);
      child.kill();
      reject(e);
    };
    const onData = (d) => {
      output += d;
      const m = output.match(/http:\/\/127\.0\.0\.1:\d+\//);
      if (m) {
        clearTimeout(timer);
        resolve({
          url: m[0],
          output: () => output,
          stop: () =>
            new Promise((done) => {
              if (child.exitCode !== null) return done();
              child.once('exit', () => done());
              child.kill();
            }),
        });
      }
    };
    child.stdout.on('data', onData);
    child.stderr.on('data', onData);
    child.once('error', fail);
    child.once('exit', (code) => fail(new Error(`jello view exited (${code}):\n${output}`)));
  });
}
