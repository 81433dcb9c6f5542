import { useMemo, useState } from 'react';
import { call, client, type Prescription } from '../api/client';
import { useImagery } from '../api/hooks';
import { imageryLabel, sortNewest, type ImageryItem } from '../lib/imagery';
import { ErrorBox } from './Status';

/**
 * NDVI prescription or management zones from an NDVI / multispectral image of the field
 * (seed 000's NDVI curve; per-cell NDVI is the area-weighted mean of the image's pixels).
 */
export function ImageryRxForm(props: { planId: number; fieldId: number; onCreated: (r: Prescription) => void }) {
  const { planId, fieldId, onCreated } = props;
  // the same cached list as the map's imagery control: an upload there shows up here
  const imagery = useImagery(fieldId);
  const items = useMemo(
    () => sortNewest(((imagery.data?.items ?? []) as ImageryItem[]).filter((i) => i.kind !== 'orthophoto')),
    [imagery.data],
  );
  const [picked, setImageId] = useState('');
  const imageId = picked || (items[0] ? String(items[0].id) : '');
  const [mode, setMode] = useState<'ndvi' | 'zones'>('ndvi');
  const [k, setK] = useState(4);
  const [minArea, setMinArea] = useState(0);
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<unknown>(null);
  if (!items.length) return null;
  return (
    <form
      className="form"
      data-testid="imagery-rx-form"
      data-write=""
      onSubmit={async (e) => {
        e.preventDefault();
        setBusy(true);
        setError(null);
        try {
          const path = { imagery_id: Number(imageId) };
          onCreated(
            mode === 'zones'
              ? await call(
                  client.POST('/api/v1/imagery/{imagery_id}/zones', {
                    params: { path },
                    body: { plan_id: planId, k, min_area_m2: minArea },
                  }),
                )
              : await call(client.POST('/api/v1/imagery/{imagery_id}/prescriptions', { params: { path }, body: { plan_id: planId } })),
          );
        } catch (err) {
          setError(err);
        } finally {
          setBusy(false);
        }
      }}
    >
      <h4>From imagery NDVI</h4>
      <label>
        Image
        <select data-testid="imagery-rx-image" value={imageId} onChange={(e) => setImageId(e.target.value)}>
          {items.map((i) => (
            <option key={i.id} value={i.id}>
              {imageryLabel(i)}
            </option>
          ))}
        </select>
      </label>
      <label>
        Build
        <select data-testid="imagery-rx-mode" value={mode} onChange={(e) => setMode(e.target.value as 'ndvi' | 'zones')}>
          <option value="ndvi">NDVI rate per cell</option>
          <option value="zones">Management zones</option>
        </select>
      </label>
      {mode === 'zones' && (
        <div className="row wrap">
          <label>
            Zones
            <input data-testid="imagery-rx-k" type="number" min={2} max={12} value={k} onChange={(e) => setK(Number(e.target.value))} />
          </label>
          <label>
            Min zone area (m²)
            <input type="number" min={0} value={minArea} onChange={(e) => setMinArea(Number(e.target.value))} />
          </label>
        </div>
      )}
      <button data-testid="imagery-rx-submit" disabled={busy}>
        {busy ? 'Computing…' : mode === 'zones' ? 'Build zone prescription' : 'Build NDVI prescription'}
      </button>
      <ErrorBox error={error} testid="imagery-rx-error" />
    </form>
  );
}
