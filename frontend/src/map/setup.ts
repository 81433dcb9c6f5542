/** MapLibre set-up shared by every screen: worker URL, base style, auth on tile requests. */
import * as maplibregl from 'maplibre-gl';
import workerUrl from 'maplibre-gl/dist/maplibre-gl-worker.mjs?url';
import 'maplibre-gl/dist/maplibre-gl.css';
import { getToken } from '../api/client';

// Without this the worker never loads under Vite and the map never goes idle (docs/architecture.md, "Stack notes").
maplibregl.setWorkerUrl(workerUrl);

const BASEMAP_KEY = 'fieldrx.basemap';

/** XYZ tile URL template from settings (localStorage) or VITE_BASEMAP_URL; '' = blank style. */
export function basemapUrl(): string {
  return localStorage.getItem(BASEMAP_KEY) ?? (import.meta.env.VITE_BASEMAP_URL as string | undefined) ?? '';
}

export function setBasemapUrl(u: string): void {
  if (u) localStorage.setItem(BASEMAP_KEY, u);
  else localStorage.setItem(BASEMAP_KEY, '');
}

/** Background-only style (works offline); adds a raster layer when an XYZ URL is configured. */
export function baseStyle(xyz = basemapUrl()): maplibregl.StyleSpecification {
  const style: maplibregl.StyleSpecification = {
    version: 8,
    sources: {},
    layers: [{ id: 'background', type: 'background', paint: { 'background-color': '#eef1ea' } }],
  };
  if (xyz) {
    style.sources.basemap = { type: 'raster', tiles: [xyz], tileSize: 256, attribution: 'Base map' };
    style.layers.push({ id: 'basemap', type: 'raster', source: 'basemap' });
  }
  return style;
}

/** Adds the bearer token to our own API requests (vector tiles); leaves third-party tiles alone. */
export function transformRequest(url: string): maplibregl.RequestParameters {
  const token = getToken();
  const ours = url.startsWith(`${location.origin}/api/`) || url.startsWith('/api/');
  if (ours && token) return { url, headers: { Authorization: `Bearer ${token}` } };
  return { url };
}

declare global {
  interface Window {
    /** Maps by name, for end-to-end tests (wait for idle, read rendered features). */
    __fieldrxMaps?: Record<string, maplibregl.Map>;
  }
}

export function createMap(container: HTMLElement, name: string, opts: Partial<maplibregl.MapOptions> = {}) {
  const map = new maplibregl.Map({
    container,
    style: baseStyle(),
    center: [10, 52],
    zoom: 3,
    transformRequest,
    attributionControl: { compact: true },
    // Keeps canvas pixels readable by screenshots in headless Chromium.
    canvasContextAttributes: { preserveDrawingBuffer: true },
    ...opts,
  });
  map.addControl(new maplibregl.NavigationControl({ visualizePitch: false }), 'top-right');
  map.addControl(new maplibregl.ScaleControl({ unit: 'metric' }), 'bottom-left');
  addArrowImage(map);
  window.__fieldrxMaps = { ...(window.__fieldrxMaps ?? {}), [name]: map };
  map.on('remove', () => {
    if (window.__fieldrxMaps?.[name] === map) delete window.__fieldrxMaps[name];
  });
  return map;
}

/** A canvas-drawn arrow as an SDF icon (no sprite server needed, so offline works). */
function addArrowImage(map: maplibregl.Map): void {
  const size = 32;
  const c = document.createElement('canvas');
  c.width = c.height = size;
  const ctx = c.getContext('2d');
  if (!ctx) return;
  ctx.fillStyle = '#000';
  ctx.beginPath();
  ctx.moveTo(size / 2, 2);
  ctx.lineTo(size - 6, size - 4);
  ctx.lineTo(size / 2, size - 11);
  ctx.lineTo(6, size - 4);
  ctx.closePath();
  ctx.fill();
  const data = ctx.getImageData(0, 0, size, size);
  const add = () => {
    if (!map.hasImage('arrow')) map.addImage('arrow', { width: size, height: size, data: data.data }, { sdf: true });
  };
  add();
  map.on('styledata', add);
}

export function absoluteApiUrl(path: string): string {
  return `${location.origin}${path}`;
}

export function fitTo(
  map: maplibregl.Map,
  bbox: [number, number, number, number] | null,
  padding: number | maplibregl.PaddingOptions = 40,
): void {
  if (!bbox) return;
  if (bbox[0] === bbox[2] && bbox[1] === bbox[3]) {
    map.jumpTo({ center: [bbox[0], bbox[1]], zoom: 16, padding: typeof padding === 'number' ? undefined : padding });
    return;
  }
  map.fitBounds(
    [
      [bbox[0], bbox[1]],
      [bbox[2], bbox[3]],
    ],
    { padding, animate: false, maxZoom: 18 },
  );
}

export { maplibregl };
