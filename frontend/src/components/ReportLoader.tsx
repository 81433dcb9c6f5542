import { useEffect, useRef } from 'react';
import type { Job, Schemas } from '../api/client';
import { useJob, useJobReport, type JobReportQuery } from '../api/hooks';
import { isTask, type TaskView } from '../lib/tasks';
import { TaskProgress } from './TaskProgress';

export type AsAppliedReport = Schemas['AsAppliedReport'];
export type KindReportOut = Schemas['KindReport'];

/** How often a running job and its report are read again (new records arrive every second). */
export const REPORT_POLL_MS = 4000;
const FINAL = new Set(['completed', 'aborted']);

/** A job that is over: no new records will come. */
export const isFinalJob = (job: Pick<Job, 'state'> | null | undefined): boolean => job != null && FINAL.has(job.state);

/**
 * A job and its report, read again every `REPORT_POLL_MS` while the job runs (through the
 * hooks' cache: the job screen, the list and the fleet share the entries). When the job turns
 * final the report is read once more, so the records sent just before the end are in it.
 *
 * A large job's report is computed by a task worker: the server answers 202 with the
 * ``report`` task, which is returned as `task` (``ReportLoading`` shows its progress; its end
 * calls `refresh`). The last report stays shown while a later read is computed that way.
 * `tick` changes with every answer: the vector tiles and the replay re-read on it.
 */
export function useLiveReport<R = AsAppliedReport | KindReportOut>(jobId: number, q: JobReportQuery = {}) {
  const jobQ = useJob(jobId, { refetchInterval: (j) => (isFinalJob(j) ? false : REPORT_POLL_MS) });
  const job = jobQ.data ?? null;
  const live = job ? !isFinalJob(job) : null;
  const repQ = useJobReport(jobId, q, { refetchInterval: live === false ? false : REPORT_POLL_MS });
  const { refetch } = repQ;
  // running -> final, seen here: one more read (not on opening a job that is already over)
  const wasLive = useRef(live);
  useEffect(() => {
    if (wasLive.current === true && live === false) void refetch();
    wasLive.current = live;
  }, [live, refetch]);

  const data = repQ.data;
  const task = isTask(data) ? data : null;
  const last = useRef<{ jobId: number; report: R } | null>(null);
  if (data && !task) last.current = { jobId, report: data as R };
  return {
    job,
    report: last.current?.jobId === jobId ? last.current.report : null,
    task,
    live: live !== false,
    tick: repQ.dataUpdatedAt,
    error: jobQ.error ?? repQ.error,
    refresh: () => void refetch(),
  };
}

/** "Computing the report" with the task's progress, or a plain loading line before the first answer. */
export function ReportLoading({ task, onDone }: { task: TaskView | null; onDone: () => void }) {
  return (
    <div className="report-loading" data-testid="report-loading" role="status" aria-busy="true">
      <p>
        <span className="spinner" aria-hidden="true" /> {task ? 'Computing the report on a worker…' : 'Loading the report…'}
      </p>
      {task && <TaskProgress key={task.id} task={task} label="Report" onDone={onDone} />}
    </div>
  );
}
