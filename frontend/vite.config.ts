/// <reference types="vitest/config" />
import { defineConfig } from 'vite';
import react from '@vitejs/plugin-react';

// Relative base: dist/ works whether the server mounts it at / or elsewhere.
// The app uses a hash router, so the server never needs deep-link fallbacks.
export default defineConfig({
  base: './',
  plugins: [react()],
  build: { outDir: 'dist', sourcemap: false, chunkSizeWarningLimit: 2000 },
  server: {
    proxy: {
      '/api': { target: process.env.FIELDRX_URL ?? 'http://127.0.0.1:8000', ws: true, changeOrigin: true },
    },
  },
  test: { include: ['src/**/*.test.ts'], environment: 'node' },
});
