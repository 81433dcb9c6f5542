import { useState } from 'react';
import type { PolygonGeom } from '../lib/geo';

/** "Paint a zone": draw a polygon on the map (the screen's ZoneDraw), then give it one rate. */
export function ZonePaintPanel(props: {
  zone: PolygonGeom | null;
  painting: boolean;
  onPaint: () => void;
  onSave: (zone: PolygonGeom, rate: number) => void;
}) {
  const { zone, painting, onPaint, onSave } = props;
  const [zoneRate, setZoneRate] = useState('');
  return (
    <>
      <div className="row">
        <button data-testid="paint-zone" data-write="" className={painting ? 'on' : ''} onClick={onPaint}>
          Paint a zone
        </button>
        {painting && <span className="small muted">Click the corners; click the first one again to close.</span>}
      </div>
      {zone && (
        <form
          className="row"
          data-testid="zone-panel"
          onSubmit={(e) => {
            e.preventDefault();
            onSave(zone, Number(zoneRate));
          }}
        >
          <input
            data-testid="zone-rate"
            type="number"
            step="any"
            placeholder="kg/ha"
            value={zoneRate}
            onChange={(e) => setZoneRate(e.target.value)}
            required
          />
          <span className="unit">kg/ha</span>
          <button data-testid="zone-save" data-write="">
            Apply to zone
          </button>
        </form>
      )}
    </>
  );
}
