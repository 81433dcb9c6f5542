import { useCallback, useEffect, useState } from 'react';
import type * as maplibregl from 'maplibre-gl';
import { call, client, errorText, formBody } from '../api/client';
import { defaultImagery, imageryLabel, opacityFromPercent, sortNewest, type ImageryItem } from '../lib/imagery';
import { isTask, progressLabel, type TaskView } from '../lib/tasks';
import { showImagery } from '../map/imagery';
import { TaskProgress } from './TaskProgress';

/**
 * Imagery picker, opacity and (for a field) GeoTIFF upload, floating over a map. Shows the
 * field's newest orthophoto by default; without a field, the organisation's imagery.
 */
export function ImageryControl(props: { map: maplibregl.Map | null; fieldId?: number }) {
  const { map, fieldId } = props;
  const [items, setItems] = useState<ImageryItem[]>([]);
  const [selected, setSelected] = useState<number | null>(null);
  const [opacityPct, setOpacityPct] = useState(100);
  const [open, setOpen] = useState(false);
  const [busy, setBusy] = useState(false);
  const [msg, setMsg] = useState('');
  const [err, setErr] = useState('');
  const [task, setTask] = useState<TaskView | null>(null);

  const load = useCallback(
    async (pick?: number) => {
      try {
        const r = await call(
          fieldId
            ? client.GET('/api/v1/fields/{field_id}/imagery', { params: { path: { field_id: fieldId } } })
            : client.GET('/api/v1/imagery'),
        );
        const list = sortNewest(r?.items ?? []);
        setItems(list);
        setSelected(pick ?? defaultImagery(list, fieldId)?.id ?? null);
      } catch {
        setItems([]); // imagery is optional: a map without it still works
      }
    },
    [fieldId],
  );
  useEffect(() => {
    void load();
  }, [load]);

  useEffect(() => {
    if (!map) return;
    const item = items.find((i) => i.id === selected) ?? null;
    // MapView hands the map over from its 'load' event, so the style is there. Not
    // whenLoaded(): while a source is still loading, loaded() and isStyleLoaded() are both
    // false and it waits for a 'load' event that has already fired (the image never showed).
    showImagery(map, item, opacityFromPercent(opacityPct));
  }, [map, items, selected, opacityPct]);

  const upload = async (form: HTMLFormElement) => {
    if (!fieldId) return;
    const fd = new FormData();
    for (const [k, v] of new FormData(form)) if (v !== '') fd.append(k, v); // blank = not given
    setBusy(true);
    setErr('');
    setMsg('Uploading and converting…');
    try {
      const item = await call(
        client.POST('/api/v1/fields/{field_id}/imagery', { params: { path: { field_id: fieldId } }, ...formBody(fd) }),
      );
      form.reset();
      if (isTask(item)) {
        // a large upload is converted by a worker: follow its task
        setMsg('');
        setTask(item);
        return;
      }
      const img = item as ImageryItem & { warnings?: string[] };
      setMsg(`Stored ${imageryLabel(img)}${img.warnings?.length ? ` — ${img.warnings.join('; ')}` : ''}`);
      await load(img.id);
    } catch (e) {
      setMsg('');
      setErr(errorText(e));
    } finally {
      setBusy(false);
    }
  };

  return (
    <div className="imagery-control" data-testid="imagery-control">
      <div className="row">
        <select
          data-testid="imagery-select"
          value={selected ?? ''}
          onChange={(e) => setSelected(e.target.value ? Number(e.target.value) : null)}
          title="Imagery under the map"
        >
          <option value="">No imagery</option>
          {items.map((i) => (
            <option key={i.id} value={i.id}>
              {imageryLabel(i)}
            </option>
          ))}
        </select>
        {fieldId !== undefined && (
          <button type="button" className="small" onClick={() => setOpen(!open)} data-testid="imagery-toggle">
            {open ? 'Close' : 'Upload'}
          </button>
        )}
      </div>
      {selected !== null && (
        <label className="row small">
          Opacity
          <input
            data-testid="imagery-opacity"
            type="range"
            min={0}
            max={100}
            value={opacityPct}
            onChange={(e) => setOpacityPct(Number(e.target.value))}
          />
        </label>
      )}
      {open && fieldId !== undefined && (
        <form
          className="small"
          onSubmit={(e) => {
            e.preventDefault();
            void upload(e.currentTarget);
          }}
        >
          <input data-testid="imagery-file" type="file" name="file" accept=".tif,.tiff,image/tiff" required />
          <div className="row wrap">
            <select name="kind" data-testid="imagery-kind" defaultValue="orthophoto">
              <option value="orthophoto">Orthophoto (RGB)</option>
              <option value="ndvi">NDVI (1 band)</option>
              <option value="multispectral">Multispectral (red + NIR)</option>
            </select>
            <input name="acquired_on" type="date" title="Acquisition date (else read from the file)" />
          </div>
          <div className="row wrap">
            <input name="red_band" type="number" min={1} placeholder="red band" style={{ width: 80 }} />
            <input name="nir_band" type="number" min={1} placeholder="NIR band" style={{ width: 80 }} />
          </div>
          <button data-testid="imagery-upload" disabled={busy}>
            {busy ? 'Working…' : 'Upload GeoTIFF'}
          </button>
        </form>
      )}
      {task && (
        <TaskProgress
          task={task}
          label="Converting"
          onDone={(t) => {
            setTask(null);
            const id = Number(t.result?.imagery_id);
            if (t.status === 'succeeded' && id) {
              setMsg('Stored the image');
              void load(id);
            } else setErr(progressLabel(t));
          }}
        />
      )}
      {msg && <p className="ok small" data-testid="imagery-msg">{msg}</p>}
      {err && <p className="error small" data-testid="imagery-error">{err}</p>}
    </div>
  );
}
