import { describe, expect, it } from 'vitest';
import { cellGridLayers, EDITED_COLOR, FIELD_STYLE, fieldBoundaryLayers, machinesGeoJSON, pointsFC, trackLayers } from './layers';

describe('layer declarations', () => {
  it('the field boundary has one style, with or without the fill', () => {
    const [fill, line] = fieldBoundaryLayers('fields', true);
    expect(fill).toMatchObject({ id: 'fields-fill', type: 'fill', paint: { 'fill-color': FIELD_STYLE.fill } });
    expect(line).toMatchObject({ id: 'fields-line', paint: { 'line-color': FIELD_STYLE.line, 'line-width': FIELD_STYLE.lineWidth } });
    expect(fieldBoundaryLayers('field', false)).toEqual([line].map((l) => ({ ...l, id: 'field-line' })));
  });

  it('cell grid: plan shading with edges; rate colours with clamped and selection layers', () => {
    expect(cellGridLayers('grid', { sourceLayer: 'cells' }).map((l) => l.id)).toEqual(['grid-fill', 'grid-line']);
    const rx = cellGridLayers('rx', { color: '#123456', clamped: true, selectedSeq: 7, sourceLayer: 'cells' });
    expect(rx.map((l) => l.id)).toEqual(['rx-fill', 'rx-clamped', 'rx-selected']);
    expect(rx[0]).toMatchObject({ 'source-layer': 'cells', paint: { 'fill-color': '#123456', 'fill-opacity': 0.85 } });
    expect(rx[2]).toMatchObject({ filter: ['==', ['get', 'seq'], 7] });
    // GeoJSON cells: no source-layer
    expect('source-layer' in cellGridLayers('k', { color: '#fff' })[0]).toBe(false);
  });

  it('cell grid: cells edited by hand get their own dashed outline', () => {
    const rx = cellGridLayers('rx', { color: '#123456', clamped: true, edited: true, selectedSeq: 7, sourceLayer: 'cells' });
    expect(rx.map((l) => l.id)).toEqual(['rx-fill', 'rx-clamped', 'rx-edited', 'rx-selected']);
    expect(rx[2]).toMatchObject({ 'source-layer': 'cells', paint: { 'line-color': EDITED_COLOR } });
    expect(JSON.stringify(rx[2].filter)).toContain('"manual"');
    expect(JSON.stringify(rx[2].filter)).toContain('"zone"');
  });

  it('track arrows only when asked', () => {
    expect(trackLayers('route', {}).map((l) => l.id)).toEqual(['route-line']);
    expect(trackLayers('route', { arrows: true }).map((l) => l.id)).toEqual(['route-line', 'route-arrows']);
  });

  it('machines without a position are left out; colour and heading flag per machine', () => {
    const fc = machinesGeoJSON([
      { machine_id: 1, lon: 10, lat: 52, heading_deg: 90, status: 'working' },
      { machine_id: 2, lon: null, lat: null, status: 'offline' },
      { machine_id: 3, lon: 11, lat: 53, heading_deg: null, status: 'idle' },
    ]);
    expect(fc.features.map((f) => f.id)).toEqual([1, 3]);
    expect(fc.features[0].properties).toMatchObject({ heading: 90, has_heading: true });
    expect(fc.features[1].properties).toMatchObject({ has_heading: false });
  });

  it('points skip missing entries', () => {
    expect(pointsFC([[1, 2], null, undefined, [3, 4]]).features).toHaveLength(2);
  });
});
