import { useCallback, useEffect, useRef, useState } from 'react';

/** One rate edit: it made version `to` from version `from`. */
export interface EditStep {
  from: number;
  to: number;
  what: string;
}

export interface RxHistory {
  push: (s: EditStep) => void;
  undo: () => Promise<void>;
  redo: () => Promise<void>;
  canUndo: boolean;
  canRedo: boolean;
  next: { undo?: EditStep; redo?: EditStep };
}

/** Ctrl+Z / Cmd+Z undo, Ctrl+Shift+Z / Ctrl+Y redo; typing in a field keeps the field's own undo. */
function isTyping(t: EventTarget | null): boolean {
  const el = t as HTMLElement | null;
  return !!el && (el.tagName === 'INPUT' || el.tagName === 'TEXTAREA' || el.tagName === 'SELECT' || el.isContentEditable);
}

/**
 * Undo / redo of this session's cell and zone rate edits. Versions are immutable: undo makes
 * the version the edit started from current again (`goTo(from)`), redo the edit's own
 * version (`goTo(to)`); a new edit clears the redo list.
 */
export function useRxHistory(goTo: (version: number) => Promise<void>): RxHistory {
  const [st, setSt] = useState<{ undo: EditStep[]; redo: EditStep[] }>({ undo: [], redo: [] });
  const busy = useRef(false);
  const push = useCallback((s: EditStep) => setSt((x) => ({ undo: [...x.undo, s], redo: [] })), []);
  const move = useCallback(
    async (dir: 'undo' | 'redo') => {
      const step = st[dir][st[dir].length - 1];
      if (!step || busy.current) return;
      busy.current = true;
      try {
        await goTo(dir === 'undo' ? step.from : step.to);
        const other = dir === 'undo' ? 'redo' : 'undo';
        setSt((x) => ({ ...x, [dir]: x[dir].slice(0, -1), [other]: [...x[other], step] }) as typeof x);
      } finally {
        busy.current = false;
      }
    },
    [st, goTo],
  );
  const undo = useCallback(() => move('undo'), [move]);
  const redo = useCallback(() => move('redo'), [move]);
  useEffect(() => {
    const onKey = (e: KeyboardEvent) => {
      if (!(e.ctrlKey || e.metaKey) || isTyping(e.target)) return;
      const k = e.key.toLowerCase();
      if (k === 'z' && !e.shiftKey) {
        e.preventDefault();
        void undo();
      } else if ((k === 'z' && e.shiftKey) || k === 'y') {
        e.preventDefault();
        void redo();
      }
    };
    window.addEventListener('keydown', onKey);
    return () => window.removeEventListener('keydown', onKey);
  }, [undo, redo]);
  return {
    push,
    undo,
    redo,
    canUndo: st.undo.length > 0,
    canRedo: st.redo.length > 0,
    next: { undo: st.undo[st.undo.length - 1], redo: st.redo[st.redo.length - 1] },
  };
}

export function UndoRedoButtons({ h }: { h: RxHistory }) {
  return (
    <div className="row" data-testid="rx-undo-redo">
      <button
        type="button"
        data-testid="rx-undo"
        data-write=""
        disabled={!h.canUndo}
        title={h.next.undo ? `Undo ${h.next.undo.what} (back to v${h.next.undo.from}) — Ctrl+Z` : 'Nothing to undo'}
        onClick={() => void h.undo()}
      >
        ↶ Undo
      </button>
      <button
        type="button"
        data-testid="rx-redo"
        data-write=""
        disabled={!h.canRedo}
        title={h.next.redo ? `Redo ${h.next.redo.what} (v${h.next.redo.to}) — Ctrl+Shift+Z` : 'Nothing to redo'}
        onClick={() => void h.redo()}
      >
        ↷ Redo
      </button>
    </div>
  );
}
