/**
 * Progress indication for every operation over a second.
 *
 * Two pieces, one rule ("say it is working before the user wonders"):
 * - `ActivityBar` (mounted once in the top bar) shows while any API call made through
 *   `client` has been pending for more than `SHOW_AFTER_MS`: nothing the screens call can be
 *   slow without a sign, even where a screen has no local indicator.
 * - `useBusy` + `Busy`: a screen's own operation (a button's save, a day's track) with a
 *   label next to the control that started it, shown after the same delay so fast answers
 *   do not flicker.
 */
import { useCallback, useEffect, useRef, useState, useSyncExternalStore } from 'react';
import type { Middleware } from 'openapi-fetch';
import { client } from '../api/client';

/** Shown only once an operation has taken this long (well under the 1 s the user notices). */
export const SHOW_AFTER_MS = 300;

let pending = 0;
const listeners = new Set<() => void>();
const emit = () => listeners.forEach((l) => l());

const counter: Middleware = {
  onRequest({ request }) {
    pending += 1;
    emit();
    return request;
  },
  onResponse({ response }) {
    pending = Math.max(0, pending - 1);
    emit();
    return response;
  },
  onError() {
    pending = Math.max(0, pending - 1);
    emit();
    // nothing returned: the next middleware sees the error and the caller gets it thrown
  },
};
let installed = false;

/** Counts the API calls in flight (once per page; App calls it). */
export function installActivityCounter(): void {
  if (installed) return;
  installed = true;
  client.use(counter);
}

function subscribe(l: () => void): () => void {
  listeners.add(l);
  return () => listeners.delete(l);
}

/** API calls in flight right now. */
export function usePendingCalls(): number {
  return useSyncExternalStore(subscribe, () => pending);
}

/** `on` delayed by `ms` (off at once): fast operations show nothing. */
export function useDelayed(on: boolean, ms = SHOW_AFTER_MS): boolean {
  const [shown, setShown] = useState(false);
  useEffect(() => {
    if (!on) {
      setShown(false);
      return;
    }
    const t = setTimeout(() => setShown(true), ms);
    return () => clearTimeout(t);
  }, [on, ms]);
  return shown;
}

/** The page-wide sign that the server is being waited for (top bar, under the nav). */
export function ActivityBar() {
  const shown = useDelayed(usePendingCalls() > 0);
  return (
    <div className={`activity ${shown ? 'on' : ''}`} role="status" aria-live="polite" data-testid="activity" data-active={shown || undefined}>
      {shown && <span className="sr-only">Working…</span>}
    </div>
  );
}

/**
 * One operation's busy flag: `run(fn)` sets it while `fn` runs (also when `fn` throws) and
 * returns `fn`'s result. Overlapping runs keep it set until the last one ends.
 */
export function useBusy(): { busy: boolean; run: <T>(fn: () => Promise<T>) => Promise<T> } {
  const [n, setN] = useState(0);
  const alive = useRef(true);
  useEffect(
    () => () => {
      alive.current = false;
    },
    [],
  );
  const run = useCallback(async <T,>(fn: () => Promise<T>): Promise<T> => {
    setN((x) => x + 1);
    try {
      return await fn();
    } finally {
      if (alive.current) setN((x) => Math.max(0, x - 1));
    }
  }, []);
  return { busy: n > 0, run };
}

/**
 * A spinner and a label next to the control whose operation is running; appears after
 * `SHOW_AFTER_MS`. `progress` (0..1) draws a bar instead when the fraction is known.
 */
export function Busy(props: { busy: boolean; label?: string; progress?: number | null; testid?: string }) {
  const shown = useDelayed(props.busy);
  if (!shown) return null;
  const p = props.progress;
  return (
    <span className="busy" role="status" aria-live="polite" data-testid={props.testid ?? 'busy'}>
      {p != null ? <progress max={1} value={p} /> : <span className="spinner" aria-hidden="true" />}
      <span>{props.label ?? 'Working…'}</span>
    </span>
  );
}
