/** Small shared bits: error banner, busy text, "not available yet" notice. */
import { useEffect, useId, useRef } from 'react';
import { ApiError, errorText } from '../api/client';

/**
 * The one error component of every form and screen: placed next to the
 * control whose action failed, it scrolls itself into view when an error appears (a form's
 * error below the fold of a 900 px screen looked like "clicking does nothing"), and marks
 * the controls of its form that the server named (`loc`, e.g. `body.headland_passes` ->
 * `name="headland_passes"`) as invalid, described by this message.
 */
export function ErrorBox({ error, testid = 'error' }: { error: unknown; testid?: string }) {
  const ref = useRef<HTMLDivElement>(null);
  const id = useId();
  const all = error instanceof ApiError ? error.parsed.items : [];
  useEffect(() => {
    const el = ref.current;
    if (!el || !error) return;
    el.scrollIntoView?.({ block: 'nearest', inline: 'nearest' });
    return markInvalid(el, id, all.map((it) => it.loc));
  }, [error]); // eslint-disable-line react-hooks/exhaustive-deps
  if (!error) return null;
  const items = all.length === 1 && all[0].message === (error as ApiError).message ? [] : all;
  return (
    <div className="error" data-testid={testid} role="alert" ref={ref} id={id}>
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

/** aria-invalid on the form controls an error names; returns the undo. */
function markInvalid(box: HTMLElement, id: string, locs: (readonly (string | number)[] | undefined)[]): () => void {
  const form = box.closest('form');
  if (!form) return () => undefined;
  const marked: Element[] = [];
  for (const loc of locs) {
    const name = [...(loc ?? [])].reverse().find((x) => typeof x === 'string' && x !== 'body');
    if (typeof name !== 'string') continue;
    for (const el of form.querySelectorAll(`[name="${CSS.escape(name)}"]`)) {
      el.setAttribute('aria-invalid', 'true');
      el.setAttribute('aria-describedby', id);
      marked.push(el);
    }
  }
  return () => {
    for (const el of marked) {
      el.removeAttribute('aria-invalid');
      if (el.getAttribute('aria-describedby') === id) el.removeAttribute('aria-describedby');
    }
  };
}

/**
 * A form check's message right under the control it is about (`id` goes into the control's
 * aria-describedby); scrolls itself into view like `ErrorBox`.
 */
export function FieldError({ id, message }: { id: string; message?: string }) {
  const ref = useRef<HTMLSpanElement>(null);
  useEffect(() => {
    if (message) ref.current?.scrollIntoView?.({ block: 'nearest', inline: 'nearest' });
  }, [message]);
  if (!message) return null;
  return (
    <span className="field-error" id={id} role="alert" ref={ref} data-testid={`field-error-${id}`}>
      {message}
    </span>
  );
}
