import { describe, expect, it } from 'vitest';
import { jobLive, withLive, type JobLive } from './livejobs';

const jobs = [
  { id: 1, state: 'running', progress: 0.028 },
  { id: 2, state: 'sent', progress: 0 },
];

describe('live job list', () => {
  it('shows what the feed said after the list was fetched', () => {
    const live = new Map<number, JobLive>([jobLive({ type: 'job', job_id: 1, state: 'completed', progress: 1 }, 2000)!]);
    expect(withLive(jobs, live, 1000)).toEqual([{ id: 1, state: 'completed', progress: 1 }, jobs[1]]);
  });
  it('lets a newer answer of the list win over older news', () => {
    const live = new Map<number, JobLive>([jobLive({ type: 'job', job_id: 1, state: 'completed', progress: 1 }, 2000)!]);
    expect(withLive(jobs, live, 3000)).toEqual(jobs);
  });
  it('keeps what a message does not say', () => {
    const live = new Map<number, JobLive>([jobLive({ type: 'job', job_id: 2, progress: 0.5 }, 2000)!]);
    expect(withLive(jobs, live, 1000)[1]).toEqual({ id: 2, state: 'sent', progress: 0.5 });
  });
  it('ignores other messages', () => {
    expect(jobLive({ type: 'position', job_id: 1 })).toBeNull();
    expect(jobLive({ type: 'job' })).toBeNull();
  });
});
