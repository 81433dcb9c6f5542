/** Small shared bits: error banner, busy text, "not available yet" notice. */
import { ApiError, errorText } from '../api/client';

export function ErrorBox({ error, testid = 'error' }: { error: unknown; testid?: string }) {
  if (!error) return null;
  const all = error instanceof ApiError ? error.parsed.items : [];
  const items = all.length === 1 && all[0].message === (error as ApiError).message ? [] : all;
  return (
    <div className="error" data-testid={testid} role="alert">
      <div>{error instanceof ApiError ? error.message : errorText(error)}</div>
      {items.length > 0 && (
        <ul data-testid={`${testid}-items`}>
          {items.map((it, i) => (
            <li key={i}>{it.message}</li>
          ))}
        </ul>
      )}
    </div>
  );
}

export function Kv({ items }: { items: [string, React.ReactNode, string?][] }) {
  return (
    <dl className="kv">
      {items.map(([k, v, tid]) => (
        <div key={k}>
          <dt>{k}</dt>
          <dd data-testid={tid}>{v}</dd>
        </div>
      ))}
    </dl>
  );
}
