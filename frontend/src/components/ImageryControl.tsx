import { useMemo, useState } from 'react';
import { call, client, errorText, formBody } from '../api/client';
import { qk, useImagery, useInvalidate } from '../api/hooks';
import { defaultImagery, imageryLabel, ndviLegend, opacityFromPercent, sortNewest, type ImageryItem } from '../lib/imagery';
import { isTask, progressLabel, type TaskView } from '../lib/tasks';
import { Imagery } from '../map/overlays/Imagery';
import { TaskProgress } from './TaskProgress';

/**
 * Imagery picker, opacity and (for a field) GeoTIFF upload, floating over a map. Shows the
 * field's newest orthophoto by default; without a field, the organisation's imagery.
 */
export function ImageryControl(props: { fieldId?: number }) {
  const { fieldId } = props;
  const imagery = useImagery(fieldId);
  const invalidate = useInvalidate();
  // imagery is optional: a map without it (or with the list refused) still works
  const items = useMemo(() => sortNewest((imagery.data?.items ?? []) as ImageryItem[]), [imagery.data]);
  /** The user's pick (null = "No imagery"); undefined = the default image. */
  const [picked, setPicked] = useState<number | null | undefined>(undefined);
  const [opacityPct, setOpacityPct] = useState(100);
  const [open, setOpen] = useState(false);
  const [busy, setBusy] = useState(false);
  const [msg, setMsg] = useState('');
  const [err, setErr] = useState('');
  const [task, setTask] = useState<TaskView | null>(null);
  const selected = picked === undefined ? (defaultImagery(items, fieldId)?.id ?? null) : picked;
  const item = items.find((i) => i.id === selected) ?? null;

  const load = async (pick?: number) => {
    await invalidate(qk.imagery(fieldId), qk.imagery());
    if (pick !== undefined) setPicked(pick);
  };

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
      <Imagery item={item} opacity={opacityFromPercent(opacityPct)} />
      <div className="row">
        <select
          data-testid="imagery-select"
          value={selected ?? ''}
          onChange={(e) => setPicked(e.target.value ? Number(e.target.value) : null)}
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
      {item && <NdviLegendBar kind={item.kind} />}
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

/** The colour ramp of an image shown as NDVI, with its values (nothing for a photo). */
function NdviLegendBar({ kind }: { kind: ImageryItem['kind'] }) {
  const l = ndviLegend(kind);
  if (!l) return null;
  return (
    <div className="ndvi-legend small" data-testid="imagery-legend" role="img" aria-label="NDVI colour scale from 0 to 1">
      <div className="legend-title">NDVI</div>
      <div className="ndvi-ramp" style={{ background: l.gradient }} />
      <div className="ndvi-ticks">
        {l.ticks.map((t) => (
          <span key={t.value} style={{ left: `${t.pct}%` }}>
            {t.value}
          </span>
        ))}
      </div>
    </div>
  );
}
