/**
 * Undo/redo over committed states (boundary drawing "undo/redo for edits
 * and boundary drawing"). Live changes while a polygon is being drawn or a corner dragged
 * `replace` what is shown without touching the history; `commit` records the step (the
 * state before it becomes undoable). Pure reducer, unit-tested; `useUndoable` wraps it.
 */
import { useCallback, useMemo, useReducer } from 'react';

export interface History<T> {
  /** Committed states before `committed`, oldest first. */
  past: T[];
  /** What is shown (may be ahead of `committed` while a change is in progress). */
  present: T;
  /** The last committed state: what the next commit puts on `past`. */
  committed: T;
  /** States undone, nearest first. */
  future: T[];
}

export type HistoryAction<T> =
  | { type: 'commit'; value: T }
  | { type: 'replace'; value: T }
  | { type: 'undo' }
  | { type: 'redo' }
  | { type: 'reset'; value: T };

/** Steps kept (older ones are dropped). */
export const HISTORY_LIMIT = 100;

export function initHistory<T>(value: T): History<T> {
  return { past: [], present: value, committed: value, future: [] };
}

function same(a: unknown, b: unknown): boolean {
  return a === b || JSON.stringify(a) === JSON.stringify(b);
}

export function historyReducer<T>(h: History<T>, a: HistoryAction<T>): History<T> {
  switch (a.type) {
    case 'replace':
      return { ...h, present: a.value };
    case 'commit':
      if (same(a.value, h.committed)) return { ...h, present: a.value };
      return { past: [...h.past, h.committed].slice(-HISTORY_LIMIT), present: a.value, committed: a.value, future: [] };
    case 'undo': {
      if (!h.past.length) return h;
      const prev = h.past[h.past.length - 1];
      return { past: h.past.slice(0, -1), present: prev, committed: prev, future: [h.committed, ...h.future] };
    }
    case 'redo': {
      if (!h.future.length) return h;
      const [next, ...rest] = h.future;
      return { past: [...h.past, h.committed], present: next, committed: next, future: rest };
    }
    case 'reset':
      return initHistory(a.value);
  }
}

/** The state a step back / forward would show (null when there is none). */
export function peek<T>(h: History<T>, dir: 'undo' | 'redo'): T | null {
  if (dir === 'undo') return h.past.length ? h.past[h.past.length - 1] : null;
  return h.future.length ? h.future[0] : null;
}

export function useUndoable<T>(initial: T) {
  const [h, dispatch] = useReducer(historyReducer<T>, initial, initHistory);
  const commit = useCallback((value: T) => dispatch({ type: 'commit', value }), []);
  const replace = useCallback((value: T) => dispatch({ type: 'replace', value }), []);
  const undo = useCallback(() => dispatch({ type: 'undo' }), []);
  const redo = useCallback(() => dispatch({ type: 'redo' }), []);
  const reset = useCallback((value: T) => dispatch({ type: 'reset', value }), []);
  return useMemo(
    () => ({ history: h, present: h.present, commit, replace, undo, redo, reset, canUndo: h.past.length > 0, canRedo: h.future.length > 0 }),
    [h, commit, replace, undo, redo, reset],
  );
}

/** Ctrl/Cmd+Z undo, Ctrl/Cmd+Shift+Z or Ctrl+Y redo; text inputs keep their own undo. */
export function undoKey(e: Pick<KeyboardEvent, 'key' | 'ctrlKey' | 'metaKey' | 'shiftKey'>, target: EventTarget | null): 'undo' | 'redo' | null {
  if (!(e.ctrlKey || e.metaKey)) return null;
  const el = target as { tagName?: string; isContentEditable?: boolean } | null;
  if (el && (el.tagName === 'INPUT' || el.tagName === 'TEXTAREA' || el.tagName === 'SELECT' || el.isContentEditable)) return null;
  const k = e.key.toLowerCase();
  if (k === 'z') return e.shiftKey ? 'redo' : 'undo';
  if (k === 'y' && !e.shiftKey) return 'redo';
  return null;
}
