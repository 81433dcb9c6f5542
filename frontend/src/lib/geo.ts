/** Small geometry helpers for the browser: live area, bounds, ring checks. */
import turfArea from '@turf/area';

export type Position = [number, number];
export type Ring = Position[];
export interface PolygonGeom {
  type: 'Polygon';
  coordinates: Ring[];
}
export interface MultiPolygonGeom {
  type: 'MultiPolygon';
  coordinates: Ring[][];
}
export type AreaGeom = PolygonGeom | MultiPolygonGeom;

/**
 * Geodesic area in m^2 (turf uses the spherical-excess formula on WGS84's mean
 * radius), good to well under 0.5 % at field scale: enough for a live readout;
 * the server's UTM area is authoritative.
 */
export function geodesicAreaM2(geom: AreaGeom | null | undefined): number {
  if (!geom) return 0;
  return turfArea({ type: 'Feature', properties: {}, geometry: geom } as never);
}

/** Close a ring (first == last) if the drawing tool left it open. */
export function closeRing(ring: Ring): Ring {
  if (ring.length === 0) return ring;
  const [a, b] = [ring[0], ring[ring.length - 1]];
  return a[0] === b[0] && a[1] === b[1] ? ring : [...ring, a];
}

/** Add hole rings to a polygon: each hole is kept only if it lies inside the outer ring. */
export function withHoles(outer: PolygonGeom, holes: Ring[]): PolygonGeom {
  const shell = outer.coordinates[0];
  const keep = holes.filter((h) => h.every((p) => pointInRing(p, shell)));
  return { type: 'Polygon', coordinates: [...outer.coordinates, ...keep.map(closeRing)] };
}

/** Even-odd ray casting; adequate in lon/lat at field scale. */
export function pointInRing([x, y]: Position, ring: Ring): boolean {
  let inside = false;
  for (let i = 0, j = ring.length - 1; i < ring.length; j = i++) {
    const [xi, yi] = ring[i];
    const [xj, yj] = ring[j];
    if (yi > y !== yj > y && x < ((xj - xi) * (y - yi)) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

function segmentsCross(a: Position, b: Position, c: Position, d: Position): boolean {
  const o = (p: Position, q: Position, r: Position) =>
    Math.sign((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]));
  return o(a, b, c) * o(a, b, d) < 0 && o(c, d, a) * o(c, d, b) < 0;
}

/**
 * First proper self-intersection of a ring, as the crossing point, or null.
 * Lets the drawing screen mark the problem before the server is asked.
 */
export function selfIntersection(ring: Ring): Position | null {
  const r = closeRing(ring);
  const n = r.length - 1;
  for (let i = 0; i < n; i++) {
    for (let j = i + 2; j < n; j++) {
      if (i === 0 && j === n - 1) continue; // neighbours through the closing vertex
      const [a, b, c, d] = [r[i], r[i + 1], r[j], r[j + 1]];
      if (segmentsCross(a, b, c, d)) {
        const den = (a[0] - b[0]) * (c[1] - d[1]) - (a[1] - b[1]) * (c[0] - d[0]);
        const t = ((a[0] - c[0]) * (c[1] - d[1]) - (a[1] - c[1]) * (c[0] - d[0])) / den;
        return [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
      }
    }
  }
  return null;
}

export type BBox = [number, number, number, number];

/** Bounding box of any GeoJSON object (walks coordinates), or null when empty. */
export function bboxOf(obj: unknown): BBox | null {
  let b: BBox | null = null;
  const visit = (c: unknown): void => {
    if (!Array.isArray(c)) return;
    if (typeof c[0] === 'number' && typeof c[1] === 'number') {
      const [x, y] = c as number[];
      if (!b) b = [x, y, x, y];
      else b = [Math.min(b[0], x), Math.min(b[1], y), Math.max(b[2], x), Math.max(b[3], y)];
      return;
    }
    for (const x of c) visit(x);
  };
  const walk = (o: unknown): void => {
    if (!o || typeof o !== 'object') return;
    const g = o as Record<string, unknown>;
    if (g.type === 'FeatureCollection') (g.features as unknown[]).forEach(walk);
    else if (g.type === 'Feature') walk(g.geometry);
    else if (g.type === 'GeometryCollection') (g.geometries as unknown[]).forEach(walk);
    else visit(g.coordinates);
  };
  walk(obj);
  return b;
}

/** Initial bearing a -> b in degrees clockwise from north (for direction arrows). */
export function bearingDeg(a: Position, b: Position): number {
  const rad = Math.PI / 180;
  const [l1, p1, l2, p2] = [a[0] * rad, a[1] * rad, b[0] * rad, b[1] * rad];
  const y = Math.sin(l2 - l1) * Math.cos(p2);
  const x = Math.cos(p1) * Math.sin(p2) - Math.sin(p1) * Math.cos(p2) * Math.cos(l2 - l1);
  return ((Math.atan2(y, x) / rad) % 360 + 360) % 360;
}

/**
 * The server's GeoJSON (RFC 7946) as the map library's type: the generated API types say
 * only "an object" for a geometry, so this is the one place that narrows it.
 */
export function asGeoJSON<T extends GeoJSON.GeoJSON = GeoJSON.FeatureCollection>(obj: object): T {
  return obj as T;
}

/** Ground distance in m between two lon/lat points (equirectangular: exact enough within a field). */
export function distanceM(a: Position, b: Position): number {
  const R = 6371008.8; // mean Earth radius (IUGG), as turf uses
  const rad = Math.PI / 180;
  const x = (b[0] - a[0]) * rad * Math.cos(((a[1] + b[1]) / 2) * rad);
  const y = (b[1] - a[1]) * rad;
  return R * Math.hypot(x, y);
}
