import { useState } from 'react';
import { call, client, type Schemas } from '../api/client';
import { qk, useInvalidate, useSoilImports } from '../api/hooks';
import { fmtCell, type SampleKey } from '../lib/soil';
import { ErrorBox } from './Status';

/**
 * A field's soil uploads (file, samples still stored, rows outside) and samples, each
 * deletable; deleting refetches the field's samples and imports.
 */
export function SoilSamples(props: {
  fieldId: number;
  soil: Schemas['SampleCollection'] | undefined;
  sampleKeys: SampleKey[];
  onMessage: (msg: string) => void;
}) {
  const { fieldId, soil, sampleKeys, onMessage } = props;
  const imports = useSoilImports(fieldId).data?.items ?? [];
  const [error, setError] = useState<unknown>(null);
  const refresh = useInvalidate();

  const remove = async (del: () => Promise<Schemas['Deleted']>, what: string) => {
    if (!confirm(`Delete ${what}?`)) return;
    setError(null);
    try {
      const r = await del();
      onMessage(`Deleted ${what} (${r.deleted} samples)`);
      await refresh(qk.soilSamples(fieldId), qk.soilImports(fieldId));
    } catch (e) {
      setError(e);
    }
  };
  const path = { field_id: fieldId };

  return (
    <>
      <ErrorBox error={error} testid="soil-delete-error" />
      {imports.length > 0 && (
        <table className="table" data-testid="soil-imports">
          <thead>
            <tr>
              <th>Import</th>
              <th>Samples</th>
              <th>Outside</th>
              <th />
            </tr>
          </thead>
          <tbody>
            {imports.map((i) => (
              <tr key={i.id} data-testid={`soil-import-${i.id}`}>
                <td>
                  {i.filename || `#${i.id}`}{' '}
                  <span className="muted small">{i.created_at ? new Date(i.created_at).toLocaleString() : ''}</span>
                </td>
                <td>{i.n_stored}</td>
                <td>{i.n_outside ? `${i.n_outside}${i.outside_stored ? ' (stored)' : ' (not stored)'}` : '–'}</td>
                <td>
                  <button
                    className="danger"
                    data-write=""
                    data-testid={`soil-import-delete-${i.id}`}
                    onClick={() =>
                      void remove(
                        () =>
                          call(
                            client.DELETE('/api/v1/fields/{field_id}/soil-imports/{import_id}', {
                              params: { path: { ...path, import_id: i.id } },
                            }),
                          ),
                        `import ${i.filename || i.id}`,
                      )
                    }
                  >
                    Delete
                  </button>
                </td>
              </tr>
            ))}
          </tbody>
        </table>
      )}
      <p className="muted" data-testid="soil-count">
        {soil?.features.length ?? 0} samples
      </p>
      {soil && soil.features.length > 0 && (
        <div className="scroll">
          <table className="table" data-testid="soil-table">
            <thead>
              <tr>
                {sampleKeys.map((k) => (
                  <th key={k}>{k}</th>
                ))}
                <th />
              </tr>
            </thead>
            <tbody>
              {soil.features.slice(0, 200).map((f) => (
                <tr key={f.properties.id}>
                  {sampleKeys.map((k) => (
                    <td key={k}>{fmtCell(f.properties[k])}</td>
                  ))}
                  <td>
                    <button
                      className="small"
                      data-write=""
                      data-testid={`soil-sample-delete-${String(f.properties.id)}`}
                      title="Delete this sample"
                      onClick={() =>
                        void remove(
                          () =>
                            call(
                              client.DELETE('/api/v1/fields/{field_id}/soil-samples/{sample_pk}', {
                                params: { path: { ...path, sample_pk: f.properties.id } },
                              }),
                            ),
                          `sample ${f.properties.sample_id}`,
                        )
                      }
                    >
                      ×
                    </button>
                  </td>
                </tr>
              ))}
            </tbody>
          </table>
        </div>
      )}
    </>
  );
}
