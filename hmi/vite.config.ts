// Vite builds the HMI into hmi/dist, which the gateway serves at `/` (`--static hmi/dist`).
// `npm run dev` proxies the APIs and the WebSocket to a running `safestate run`
// (SAFESTATE_URL, default http://127.0.0.1:8080).
import { defineConfig } from 'vite';

const target = process.env.SAFESTATE_URL ?? 'http://127.0.0.1:8080';

export default defineConfig({
  base: './',
  build: {
    outDir: 'dist',
    emptyOutDir: true,
    target: 'es2022',
    chunkSizeWarningLimit: 800,
  },
  server: {
    proxy: {
      '/api': target,
      '/metrics': target,
      '/ws': { target: target.replace(/^http/, 'ws'), ws: true },
    },
  },
});
