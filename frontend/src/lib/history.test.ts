import { describe, expect, it } from 'vitest';
import { historyReducer, initHistory, peek, undoKey, type History } from './history';

const run = (h: History<number>, ...as: Parameters<typeof historyReducer<number>>[1][]) => as.reduce(historyReducer<number>, h);

describe('undo history', () => {
  it('live changes are not steps; a commit is, and undo returns to the committed state before it', () => {
    let h = initHistory(0);
    h = run(h, { type: 'replace', value: 1 }, { type: 'replace', value: 2 }, { type: 'commit', value: 3 });
    expect(h.past).toEqual([0]);
    h = run(h, { type: 'replace', value: 4 }, { type: 'commit', value: 5 });
    expect(h.past).toEqual([0, 3]);
    expect(peek(h, 'undo')).toBe(3);
    h = run(h, { type: 'undo' });
    expect(h.present).toBe(3);
    h = run(h, { type: 'undo' });
    expect(h.present).toBe(0);
    expect(run(h, { type: 'undo' })).toBe(h); // nothing more to undo
    h = run(h, { type: 'redo' }, { type: 'redo' });
    expect(h.present).toBe(5);
    expect(peek(h, 'redo')).toBeNull();
  });

  it('a new commit after undo drops the redo branch', () => {
    let h = run(initHistory(0), { type: 'commit', value: 1 }, { type: 'commit', value: 2 }, { type: 'undo' });
    expect(h.future).toEqual([2]);
    h = run(h, { type: 'commit', value: 7 });
    expect(h.future).toEqual([]);
    expect(h.past).toEqual([0, 1]);
  });

  it('committing the unchanged state is not a step', () => {
    const h = run(initHistory(0), { type: 'commit', value: 1 }, { type: 'commit', value: 1 });
    expect(h.past).toEqual([0]);
  });

  it('keys: Ctrl+Z, Ctrl+Shift+Z, Ctrl+Y; not inside a text box', () => {
    const e = (key: string, shiftKey = false) => ({ key, shiftKey, ctrlKey: true, metaKey: false });
    expect(undoKey(e('z'), null)).toBe('undo');
    expect(undoKey(e('Z', true), null)).toBe('redo');
    expect(undoKey(e('y'), null)).toBe('redo');
    expect(undoKey({ ...e('z'), ctrlKey: false }, null)).toBeNull();
    expect(undoKey(e('z'), { tagName: 'INPUT' } as unknown as EventTarget)).toBeNull();
  });
});
