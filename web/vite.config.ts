import { defineConfig } from 'vitest/config';

// The editor builds into the Python package so that `inkwarp edit` can serve it.
export default defineConfig({
  base: './',
  build: {
    outDir: '../python/inkwarp/editor',
    emptyOutDir: true,
    target: 'es2022',
    assetsInlineLimit: 0,
  },
  worker: { format: 'es' },
  test: {
    include: ['tests/**/*.test.ts'],
    environment: 'node',
  },
});
