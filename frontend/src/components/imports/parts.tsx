import { useEffect, useState } from 'react';
import { formBody, type Schemas } from '../../api/client';
import { ErrorBox } from '../Status';

/** Shared pieces of the import assistant's panels. */
type Field = Schemas['FieldFeature'];
export type Farm = { id: number; name: string };
export type Rx = { id: number; name: string };
export type Done = (msg: string, link?: string) => void;
export type Dict = Record<string, unknown>;
export type Row = Record<string, any>; // eslint-disable-line @typescript-eslint/no-explicit-any
export type { Field };

export const fmtDate = (t: number | null | undefined) => (t == null ? '–' : new Date(t * 1000).toISOString().slice(0, 16).replace('T', ' '));
export const num = (x: unknown, d = 1) => (typeof x === 'number' ? x.toFixed(d) : '–');

export function filesBody(files: File[], key = 'files') {
  const fd = new FormData();
  for (const f of files) fd.append(key, f, f.name);
  return formBody(fd);
}

/** Runs a preview whenever its inputs change; keeps the last answer and error. */
export function usePreview<T>(run: (() => Promise<T>) | null, deps: unknown[]) {
  const [data, setData] = useState<T | null>(null);
  const [error, setError] = useState<unknown>(null);
  const [busy, setBusy] = useState(false);
  useEffect(() => {
    if (!run) return;
    let live = true;
    setBusy(true);
    setError(null);
    run()
      .then((d) => live && setData(d))
      .catch((e) => {
        if (!live) return;
        setData(null);
        setError(e);
      })
      .finally(() => live && setBusy(false));
    return () => {
      live = false;
    };
    // eslint-disable-next-line react-hooks/exhaustive-deps
  }, deps);
  return { data, error, busy };
}

export function Confirm({ label, disabled, onConfirm }: { label: string; disabled?: boolean; onConfirm: () => Promise<void> }) {
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<unknown>(null);
  return (
    <div>
      <button
        data-testid="import-confirm"
        data-write=""
        disabled={disabled || busy}
        onClick={async () => {
          setBusy(true);
          setError(null);
          try {
            await onConfirm();
          } catch (e) {
            setError(e);
          } finally {
            setBusy(false);
          }
        }}
      >
        {busy ? 'Importing… (all or nothing)' : label}
      </button>
      <ErrorBox error={error} testid="import-confirm-error" />
    </div>
  );
}

export function Skipped({ items }: { items: Row[] }) {
  if (!items.length) return null;
  return (
    <details open={items.some((s) => s.bad)} data-testid="import-skipped">
      <summary>
        Skipped ({items.length}){items.some((s) => s.bad) ? ' — some refused, the rest imports' : ''}
      </summary>
      <ul className="list">
        {items.map((s, i) => (
          <li key={i} className={s.bad ? 'error' : 'muted'} data-testid={s.bad ? 'import-refused' : undefined}>
            <strong>{s.what}</strong>: {s.why}
          </li>
        ))}
      </ul>
    </details>
  );
}

