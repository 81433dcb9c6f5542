import { describe, expect, it } from 'vitest';
import { addSlotAnchors, slotAnchorId, syncOverlay, type MapLike, type OverlaySpec } from './overlay';
import { cellGridLayers, fieldBoundaryLayers } from './layers';

/**
 * A stand-in for maplibre's style: an ordered layer list and a source table, with the same
 * rules the real map enforces (a duplicate id or an unknown before-id throws), and a log of
 * the calls so the tests can say "only a setData".
 */
class StyleDouble {
  layers: { id: string; source?: string; paint: Record<string, unknown>; filter?: unknown }[] = [];
  sources = new Map<string, { spec: unknown; data?: unknown }>();
  log: string[] = [];
  asMap(): MapLike {
    const self = this;
    return {
      addSource(id: string, spec: { data?: unknown }) {
        if (self.sources.has(id)) throw new Error(`source ${id} exists`);
        self.sources.set(id, { spec, data: spec.data });
        self.log.push(`addSource ${id}`);
      },
      removeSource(id: string) {
        if (self.layers.some((l) => l.source === id)) throw new Error(`source ${id} in use`);
        self.sources.delete(id);
        self.log.push(`removeSource ${id}`);
      },
      getSource(id: string) {
        const s = self.sources.get(id);
        return s
          ? {
              setData(d: unknown) {
                s.data = d;
                self.log.push(`setData ${id}`);
              },
            }
          : undefined;
      },
      addLayer(l: { id: string; source?: string; paint?: Record<string, unknown>; filter?: unknown }, before?: string) {
        if (self.layers.some((x) => x.id === l.id)) throw new Error(`layer ${l.id} exists`);
        if (l.source && !self.sources.has(l.source)) throw new Error(`no source ${l.source}`);
        const at = before === undefined ? self.layers.length : self.layers.findIndex((x) => x.id === before);
        if (at < 0) throw new Error(`no layer ${before}`);
        self.layers.splice(at, 0, { id: l.id, source: l.source, paint: { ...(l.paint ?? {}) }, filter: l.filter });
        self.log.push(`addLayer ${l.id}`);
      },
      removeLayer(id: string) {
        self.layers = self.layers.filter((l) => l.id !== id);
        self.log.push(`removeLayer ${id}`);
      },
      getLayer(id: string) {
        return self.layers.find((l) => l.id === id);
      },
      moveLayer(id: string) {
        const l = self.layers.find((x) => x.id === id)!;
        self.layers = [...self.layers.filter((x) => x.id !== id), l];
        self.log.push(`moveLayer ${id}`);
      },
      setPaintProperty(id: string, k: string, v: unknown) {
        self.layers.find((l) => l.id === id)!.paint[k] = v;
        self.log.push(`setPaintProperty ${id} ${k}`);
      },
      setLayoutProperty(id: string, k: string) {
        self.log.push(`setLayoutProperty ${id} ${k}`);
      },
      setFilter(id: string, f: unknown) {
        self.layers.find((l) => l.id === id)!.filter = f;
        self.log.push(`setFilter ${id}`);
      },
      setLayerZoomRange(id: string) {
        self.log.push(`setLayerZoomRange ${id}`);
      },
    } as unknown as MapLike;
  }
  ids(): string[] {
    return this.layers.map((l) => l.id);
  }
}

const fc = (n: number): GeoJSON.FeatureCollection => ({
  type: 'FeatureCollection',
  features: Array.from({ length: n }, () => ({ type: 'Feature', properties: {}, geometry: { type: 'Point', coordinates: [0, 0] } })),
});

const boundary = (data: GeoJSON.GeoJSON): OverlaySpec => ({
  id: 'field',
  slot: 'line',
  source: { type: 'geojson', data },
  layers: fieldBoundaryLayers('field', true),
});
const grid = (tiles: string, color: unknown, sel: number | null = null): OverlaySpec => ({
  id: 'rx',
  slot: 'grid',
  source: { type: 'vector', tiles: [tiles] },
  layers: cellGridLayers('rx', { color, clamped: true, selectedSeq: sel, sourceLayer: 'cells' }),
});

describe('syncOverlay', () => {
  it('adds, updates data with one setData, and removes everything it added', () => {
    const s = new StyleDouble();
    const map = s.asMap();
    const a = boundary(fc(1));
    expect(syncOverlay(map, null, a)).toBe('added');
    expect(s.ids()).toEqual(['field-fill', 'field-line']);
    s.log = [];
    const b = boundary(fc(2));
    expect(syncOverlay(map, a, b)).toBe('updated');
    expect(s.log).toEqual(['setData field']);
    expect(syncOverlay(map, b, b)).toBe('none');
    expect(syncOverlay(map, b, null)).toBe('removed');
    expect(s.ids()).toEqual([]);
    expect(s.sources.size).toBe(0);
  });

  it('stacks by slot, whatever the mount order: imagery < grid < boundary < top', () => {
    const s = new StyleDouble();
    const map = s.asMap();
    s.layers.push({ id: 'background', paint: {} });
    addSlotAnchors(map);
    syncOverlay(map, null, boundary(fc(1)));
    syncOverlay(map, null, { id: 'problems', slot: 'top', source: { type: 'geojson', data: fc(0) }, layers: [{ id: 'problems', type: 'circle' }] });
    syncOverlay(map, null, grid('/t/{z}/{x}/{y}', '#f00'));
    // a drawing tool adding its own layers on top afterwards
    s.layers.push({ id: 'td-polygon', paint: {} });
    syncOverlay(map, null, {
      id: 'imagery',
      slot: 'imagery',
      source: { type: 'raster', tiles: ['/i/{z}/{x}/{y}'] },
      layers: [{ id: 'imagery', type: 'raster' }],
    });
    const ids = s.ids().filter((i) => !i.startsWith('slot:'));
    expect(ids).toEqual(['background', 'imagery', 'rx-fill', 'rx-clamped', 'rx-selected', 'field-fill', 'field-line', 'problems', 'td-polygon']);
    expect(s.ids().indexOf(slotAnchorId('grid'))).toBeGreaterThan(s.ids().indexOf('rx-selected'));
    // an update of a 'top' overlay brings it back above the drawing tool
    const p = { id: 'problems', slot: 'top' as const, source: { type: 'geojson' as const, data: fc(0) }, layers: [{ id: 'problems', type: 'circle' as const }] };
    syncOverlay(map, p, { ...p, source: { type: 'geojson', data: fc(1) } });
    expect(s.ids().at(-1)).toBe('problems');
  });

  it('a new colour scale or selection is a paint/filter change, not a new source', () => {
    const s = new StyleDouble();
    const map = s.asMap();
    const a = grid('/rx/1/{z}/{x}/{y}', ['step', ['get', 'rate_kg_ha'], '#000', 100, '#fff']);
    syncOverlay(map, null, a);
    s.log = [];
    const b = grid('/rx/1/{z}/{x}/{y}', ['step', ['get', 'rate_kg_ha'], '#000', 120, '#fff'], 42);
    expect(syncOverlay(map, a, b)).toBe('updated');
    expect(s.log).toEqual(['setPaintProperty rx-fill fill-color', 'setFilter rx-selected']);
    expect(s.layers.find((l) => l.id === 'rx-selected')!.filter).toEqual(['==', ['get', 'seq'], 42]);
  });

  it('a new tile URL (another version) re-creates the source and its layers', () => {
    const s = new StyleDouble();
    const map = s.asMap();
    const a = grid('/rx/1/1/{z}/{x}/{y}', '#f00');
    syncOverlay(map, null, a);
    s.log = [];
    expect(syncOverlay(map, a, grid('/rx/1/2/{z}/{x}/{y}', '#f00'))).toBe('added');
    expect(s.log[0]).toBe('removeLayer rx-fill');
    expect(s.log).toContain('addSource rx');
    expect(s.ids()).toEqual(['rx-fill', 'rx-clamped', 'rx-selected']);
  });

  it('a different set of layers is swapped on the same source', () => {
    const s = new StyleDouble();
    const map = s.asMap();
    const a = boundary(fc(1));
    syncOverlay(map, null, a);
    s.log = [];
    const b = { ...a, layers: fieldBoundaryLayers('field', false) };
    syncOverlay(map, a, b);
    expect(s.ids()).toEqual(['field-line']);
    expect(s.log).not.toContain('addSource field');
  });

  it('replaces left-overs of the same id instead of throwing', () => {
    const s = new StyleDouble();
    const map = s.asMap();
    syncOverlay(map, null, boundary(fc(1)));
    expect(() => syncOverlay(map, null, boundary(fc(3)))).not.toThrow();
    expect(s.ids()).toEqual(['field-fill', 'field-line']);
  });
});
