import { defineConfig } from 'vite';

// Relative asset paths, so the bundle works wherever `jello view` (or any static server) puts it.
export default defineConfig({
  base: './',
  build: {
    target: 'es2022',
    outDir: 'dist',
    emptyOutDir: true,
    // three.js alone is ~600 kB minified; one chunk is fine for a local viewer.
    chunkSizeWarningLimit: 1500,
  },
  // The stepping worker is an ES module (it imports the wasm core's bindings).
  worker: {
    format: 'es',
  },
});
