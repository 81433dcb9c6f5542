import { describe, expect, it } from 'vitest';
import { isFinal, isTask, pollTask, progressLabel, type TaskView } from './tasks';

const view = (over: Partial<TaskView> = {}): TaskView => ({
  id: 7,
  kind: 'plan',
  status: 'running',
  progress: 0.4,
  message: 'cutting the path into cells',
  result: null,
  result_url: null,
  error: null,
  url: '/api/v1/tasks/7',
  ...over,
});

describe('isTask', () => {
  it('recognises a 202 task body and nothing else', () => {
    expect(isTask(view({ status: 'queued' }))).toBe(true);
    expect(isTask({ id: 3, kind: 'orthophoto', tiles: '/api/v1/tiles/imagery/3/{z}/{x}/{y}.png' })).toBe(false);
    expect(isTask(null)).toBe(false);
    expect(isTask('x')).toBe(false);
  });
});

describe('progressLabel', () => {
  it('says percent and stage while running', () => {
    expect(progressLabel(view({ progress: 0.456 }))).toBe('45 % · cutting the path into cells');
    expect(progressLabel(view({ progress: 1.7, message: '' }))).toBe('100 %');
  });
  it('says what ended and why it failed', () => {
    expect(progressLabel(view({ status: 'queued', progress: 0 }))).toBe('Waiting for a worker…');
    expect(progressLabel(view({ status: 'failed', error: 'field 3 not found' }))).toBe('Failed: field 3 not found');
    expect(progressLabel(view({ status: 'cancelled' }))).toBe('Cancelled');
    expect(progressLabel(view({ status: 'succeeded', progress: 1 }))).toBe('Done');
    expect(isFinal(view({ status: 'cancelled' }))).toBe(true);
    expect(isFinal(view())).toBe(false);
  });
});

describe('pollTask', () => {
  it('reads until the task ends, reporting every view, backing off while nothing changes', async () => {
    const seq = [
      view({ status: 'queued', progress: 0 }),
      view({ progress: 0.05 }),
      view({ progress: 0.05 }),
      view({ progress: 0.05 }),
      view({ progress: 0.6 }),
      view({ status: 'succeeded', progress: 1, result_url: '/api/v1/plans/9' }),
    ];
    const urls: string[] = [];
    const waits: number[] = [];
    const seen: number[] = [];
    const done = await pollTask(
      async (u) => {
        urls.push(u);
        return seq.shift()!;
      },
      '/api/v1/tasks/7',
      { intervalMs: 100, sleep: async (ms) => void waits.push(ms), onUpdate: (t) => seen.push(t.progress) },
    );
    expect(done.status).toBe('succeeded');
    expect(done.result_url).toBe('/api/v1/plans/9');
    expect(urls).toEqual(Array(6).fill('/api/v1/tasks/7'));
    expect(seen).toEqual([0, 0.05, 0.05, 0.05, 0.6, 1]);
    expect(waits).toEqual([100, 100, 200, 400, 100]);
  });

  it('stops when aborted', async () => {
    const signal = { aborted: false };
    let reads = 0;
    const last = await pollTask(
      async () => {
        reads += 1;
        return view();
      },
      '/api/v1/tasks/7',
      {
        signal,
        sleep: async () => {
          signal.aborted = true;
        },
      },
    );
    expect(reads).toBe(1);
    expect(last.status).toBe('running');
  });
});
