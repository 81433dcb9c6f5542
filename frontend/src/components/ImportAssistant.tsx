import { useEffect, useState } from 'react';
import { call, client } from '../api/client';
import { KIND_LABELS, recognise, zipNames, type ImportKind } from '../lib/importKind';
import { IsoxmlPanel } from './imports/IsoxmlPanel';
import { AsAppliedPanel, FieldsPanel, TimelogPanel } from './imports/LogPanels';
import { RxShapefilePanel } from './imports/RxShapefilePanel';
import type { Done, Farm, Field, Rx } from './imports/parts';

/**
 * One import for every format FieldRx reads: pick or drop files, FieldRx recognises what
 * they are (the user can correct it), shows the server's preview — what will be created,
 * matched and skipped, with areas, rates, record counts, dates and positions — asks for the
 * mapping where one is needed, and stores all or nothing on "Import".
 */
export function ImportAssistant({
  fields,
  farms,
  onDone,
  initialFiles = [],
}: {
  fields: Field[];
  farms: Farm[];
  onDone: Done;
  initialFiles?: File[];
}) {
  const [files, setFiles] = useState<File[]>([]);
  const [kind, setKind] = useState<ImportKind | null>(null);
  const [why, setWhy] = useState('');
  const [rxs, setRxs] = useState<Rx[]>([]);
  const [over, setOver] = useState(false);

  useEffect(() => {
    if (initialFiles.length) void take(initialFiles);
    // eslint-disable-next-line react-hooks/exhaustive-deps
  }, []);

  useEffect(() => {
    call(client.GET('/api/v1/prescriptions'))
      .then((r) => setRxs((r.items as Rx[]).map((x) => ({ id: x.id, name: x.name }))))
      .catch(() => setRxs([]));
  }, []);

  const take = async (list: File[]) => {
    if (!list.length) return;
    const described = await Promise.all(
      list.map(async (f) => ({ name: f.name, members: f.name.toLowerCase().endsWith('.zip') ? zipNames(await f.arrayBuffer()) : undefined })),
    );
    const r = recognise(described);
    setFiles(list);
    setKind(r.kind);
    setWhy(r.why);
  };

  return (
    <div
      className={`import-assistant${over ? ' drop-over' : ''}`}
      data-testid="import-assistant"
      onDragOver={(e) => {
        e.preventDefault();
        setOver(true);
      }}
      onDragLeave={() => setOver(false)}
      onDrop={(e) => {
        e.preventDefault();
        setOver(false);
        void take([...e.dataTransfer.files]);
      }}
    >
      <p className="muted">
        Drop files here or choose them: TASKDATA (zip or TASKDATA.XML with its .BIN files), TimeLogs (TLG .XML + .BIN), Shapefiles (zip), GeoJSON, KML, CSV.
      </p>
      <input data-testid="import-files" data-write="" type="file" multiple onChange={(e) => void take([...(e.target.files ?? [])])} />
      {files.length > 0 && (
        <p data-testid="import-kind" data-kind={kind ?? ''}>
          {files.map((f) => f.name).join(', ')}: {kind ? KIND_LABELS[kind] : 'not recognised'} ({why}){' '}
          <select data-testid="import-kind-select" value={kind ?? ''} onChange={(e) => setKind((e.target.value || null) as ImportKind | null)}>
            <option value="">–</option>
            {Object.entries(KIND_LABELS).map(([k, l]) => (
              <option key={k} value={k}>
                {l}
              </option>
            ))}
          </select>
        </p>
      )}
      {files.length > 0 && kind === 'isoxml' && <IsoxmlPanel key={files.map((f) => f.name).join()} files={files} onDone={onDone} />}
      {files.length > 0 && kind === 'rx-shapefile' && <RxShapefilePanel file={files[0]} fields={fields} onDone={onDone} />}
      {files.length > 0 && kind === 'timelog' && <TimelogPanel files={files} rxs={rxs} onDone={onDone} />}
      {files.length > 0 && kind === 'as-applied' && <AsAppliedPanel file={files[0]} rxs={rxs} onDone={onDone} />}
      {files.length > 0 && kind === 'fields' && <FieldsPanel file={files[0]} farms={farms} onDone={onDone} />}
    </div>
  );
}
