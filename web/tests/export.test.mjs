// `jello run --export OUT.glb`: the file passes the Khronos glTF validator (npm gltf-validator)
// with no errors and no warnings, and holds what the run computed: the lattice surface's 296
// vertices and 588 triangles, one morph target per later frame, an animation over the simulated
// time, and a last frame equal (to 32-bit precision) to the state `--save` writes (turned from
// Jello's z-up frame into glTF's y-up one).
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { test } from 'node:test';
import validator from 'gltf-validator';
import { JELLO, ROOT } from './server.mjs';

/** The JSON and binary chunks of a GLB file. */
function readGlb(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  assert.equal(view.getUint32(0, true), 0x46546c67, 'magic glTF');
  assert.equal(view.getUint32(8, true), bytes.byteLength, 'declared length');
  const jsonLength = view.getUint32(12, true);
  const json = JSON.parse(new TextDecoder().decode(bytes.subarray(20, 20 + jsonLength)));
  const binStart = 20 + jsonLength + 8;
  const bin = bytes.subarray(binStart, binStart + view.getUint32(20 + jsonLength, true));
  return { json, bin };
}

/** The floats of a (dense) float accessor. */
function floats({ json, bin }, index) {
  const accessor = json.accessors[index];
  const bufferView = json.bufferViews[accessor.bufferView];
  const width = { SCALAR: 1, VEC3: 3 }[accessor.type];
  const start = bin.byteOffset + (bufferView.byteOffset ?? 0) + (accessor.byteOffset ?? 0);
  return new Float32Array(bin.buffer.slice(start, start + 4 * width * accessor.count));
}

/** Positions of the points of a world file (after the header and field), as [x, y, z]. */
function worldPositions(text) {
  const t = text.trim().split(/\s+/);
  let i = 1 + 2 + 4 + 1;
  i += 1 + (t[i] === '1' ? 4 : 0);
  const res = Number(t[i]);
  i += 1 + 3 * res ** 3;
  const p = [];
  for (let n = 0; n < 512; n++) p.push([0, 1, 2].map((c) => Number(t[i + 3 * n + c])));
  return p;
}

test('jello run --export writes a valid animated glTF of the run', async () => {
  const dir = mkdtempSync(join(tmpdir(), 'jello-export-'));
  try {
    const glbPath = join(dir, 'rotate.glb');
    const savePath = join(dir, 'after.w');
    const out = execFileSync(
      JELLO,
      ['run', join(ROOT, 'examples', 'rotate.w'), '--time', '1', '--export', glbPath,
        '--fps', '24', '--save', savePath, '-q'],
      { encoding: 'utf8' },
    );
    const bytes = new Uint8Array(readFileSync(glbPath));
    const report = await validator.validateBytes(bytes);
    assert.equal(report.issues.numErrors, 0, JSON.stringify(report.issues.messages, null, 1));
    assert.equal(report.issues.numWarnings, 0, JSON.stringify(report.issues.messages, null, 1));
    assert.equal(report.info.animationCount, 1);

    const glb = readGlb(bytes);
    const primitive = glb.json.meshes[0].primitives[0];
    assert.equal(glb.json.accessors[primitive.attributes.POSITION].count, 296);
    assert.equal(glb.json.accessors[primitive.indices].count, 3 * 588);
    // rotate.w steps at dt = 0.001: a frame every round(1000/24) = 42 steps, 23 frames in
    // 1000 steps, plus the initial one and the final state.
    const frames = primitive.targets.length + 1;
    assert.equal(frames, 1 + 23 + 1);
    assert.match(out, new RegExp(`${frames} frames exported`));
    const sampler = glb.json.animations[0].samplers[0];
    const times = floats(glb, sampler.input);
    assert.equal(times.length, frames);
    assert.equal(times[0], 0);
    assert.ok(Math.abs(times[frames - 1] - 1) < 1e-6, `last time ${times[frames - 1]}`);

    // The weights: at key k, target k − 1 alone at 1 (sparse: one index per key past the first).
    const weights = glb.json.accessors[sampler.output];
    assert.equal(weights.count, frames * (frames - 1));
    assert.equal(weights.bufferView, undefined, 'zeros but for the sparse entries');
    const sparse = weights.sparse;
    assert.equal(sparse.count, frames - 1);
    // `n` 4-byte numbers of a buffer view (glb.bin.byteOffset is within bytes.buffer).
    const at = (view, n) => {
      const start = glb.bin.byteOffset + (glb.json.bufferViews[view].byteOffset ?? 0);
      return bytes.buffer.slice(start, start + 4 * n);
    };
    const hot = new Uint32Array(at(sparse.indices.bufferView, sparse.count));
    const ones = new Float32Array(at(sparse.values.bufferView, sparse.count));
    for (let k = 1; k < frames; k++) {
      assert.equal(hot[k - 1], k * (frames - 1) + (k - 1), `key ${k}`);
      assert.equal(ones[k - 1], 1);
    }

    // The last frame (frame 0 plus the last target) is the saved state's surface, to f32.
    const base = floats(glb, primitive.attributes.POSITION);
    const last = floats(glb, primitive.targets[frames - 2].POSITION);
    const saved = worldPositions(readFileSync(savePath, 'utf8'));
    // Surface points in flat-index order (i, j or k on the boundary of the 8³ lattice).
    const surface = [];
    for (let n = 0; n < 512; n++) {
      const [i, j, k] = [Math.floor(n / 64), Math.floor(n / 8) % 8, n % 8];
      if ([i, j, k].some((c) => c === 0 || c === 7)) surface.push(n);
    }
    assert.equal(surface.length, 296);
    // glTF is y-up: Jello's (x, y, z) is stored as (x, z, −y).
    let worst = 0;
    surface.forEach((n, v) => {
      const [x, y, z] = saved[n];
      [x, z, -y].forEach((want, c) => {
        worst = Math.max(worst, Math.abs(base[3 * v + c] + last[3 * v + c] - want));
      });
    });
    assert.ok(worst < 1e-5, `last frame differs from the saved state by ${worst} m`);
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
});

test('a failed export leaves no file behind', () => {
  const dir = mkdtempSync(join(tmpdir(), 'jello-export-'));
  try {
    const glbPath = join(dir, 'x.glb');
    // A world that blows up at its dt (exit 3): nothing is written.
    let code = 0;
    try {
      execFileSync(JELLO, ['run', join(ROOT, 'examples', 'rotate.w'), '--dt', '0.01',
        '--export', glbPath, '-q'], { stdio: 'pipe' });
    } catch (e) {
      code = e.status;
    }
    assert.equal(code, 3);
    assert.throws(() => readFileSync(glbPath), /ENOENT/);
    // More frames than one file holds: refused before the run (exit 1), nothing written.
    code = 0;
    let stderr = '';
    try {
      execFileSync(JELLO, ['run', join(ROOT, 'examples', 'rotate.w'), '--steps', '70000',
        '--fps', '1000', '--export', glbPath, '-q'], { stdio: 'pipe' });
    } catch (e) {
      code = e.status;
      stderr = String(e.stderr);
    }
    assert.equal(code, 1);
    assert.match(stderr, /more than the 4096 one glTF file holds/);
    assert.throws(() => readFileSync(glbPath), /ENOENT/);
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
});

/** A torus about the z axis (radii R and r, m × n quads) as OBJ text, and its vertices. */
function torusObj(R, r, m, n, z) {
  const vertices = [];
  const lines = [];
  for (let i = 0; i < m; i++) {
    const u = (2 * Math.PI * i) / m;
    for (let j = 0; j < n; j++) {
      const v = (2 * Math.PI * j) / n;
      const p = [(R + r * Math.cos(v)) * Math.cos(u), (R + r * Math.cos(v)) * Math.sin(u), r * Math.sin(v) + z];
      vertices.push(p);
      lines.push(`v ${p.join(' ')}`);
    }
  }
  const at = (i, j) => (i % m) * n + (j % n) + 1;
  for (let i = 0; i < m; i++) {
    for (let j = 0; j < n; j++) {
      lines.push(`f ${at(i, j)} ${at(i + 1, j)} ${at(i + 1, j + 1)}`);
      lines.push(`f ${at(i, j)} ${at(i + 1, j + 1)} ${at(i, j + 1)}`);
    }
  }
  return { text: lines.join('\n') + '\n', vertices, triangles: 2 * m * n };
}

test('a scene made from a mesh exports its skin as a valid animated glTF', async () => {
  const dir = mkdtempSync(join(tmpdir(), 'jello-export-scene-'));
  try {
    const torus = torusObj(0.5, 0.2, 24, 12, 1.0);
    writeFileSync(join(dir, 'ring.obj'), torus.text);
    const scene = join(dir, 'ring.toml');
    execFileSync(JELLO, ['create', scene, '--mesh', join(dir, 'ring.obj'), '--cells', '10',
      '--sphere', '0,0,0,0.4', '--gravity', '0,0,-9.81'], { encoding: 'utf8' });
    const glbPath = join(dir, 'ring.glb');
    execFileSync(JELLO, ['run', scene, '--time', '1', '--export', glbPath, '-q'], { encoding: 'utf8' });
    const bytes = new Uint8Array(readFileSync(glbPath));
    const report = await validator.validateBytes(bytes);
    assert.equal(report.issues.numErrors, 0, JSON.stringify(report.issues.messages, null, 1));
    assert.equal(report.issues.numWarnings, 0, JSON.stringify(report.issues.messages, null, 1));
    const glb = readGlb(bytes);
    const primitive = glb.json.meshes[0].primitives[0];
    // The skin is the input mesh: its vertices, its triangles, at rest in the first frame.
    assert.equal(glb.json.accessors[primitive.attributes.POSITION].count, torus.vertices.length);
    assert.equal(glb.json.accessors[primitive.indices].count, 3 * torus.triangles);
    const first = floats(glb, primitive.attributes.POSITION);
    torus.vertices.forEach(([x, y, z], v) => {
      const want = [x, z, -y];
      for (let c = 0; c < 3; c++) {
        assert.ok(Math.abs(first[3 * v + c] - want[c]) < 1e-6, `vertex ${v}`);
      }
    });
    assert.equal(primitive.targets.length + 1, 31, '1 s at 30 frames per second, and the start');
  } finally {
    rmSync(dir, { recursive: true, force: true });
  }
});
