import { useCallback, useRef, useState } from 'react';
import { call, client, type Schemas } from '../api/client';
import { isTask, type TaskView } from '../lib/tasks';
import { TaskProgress } from './TaskProgress';

export type AsAppliedReport = Schemas['AsAppliedReport'];

/**
 * The job's as-applied report (without cells). A large job's report is computed by a task
 * worker: the server answers 202 with the ``report`` task, whose progress is shown
 * (``ReportLoading``); once it ends the report is read again (then from the task's snapshot).
 */
export function useJobReport(jobId: number) {
  const [report, setReport] = useState<AsAppliedReport | null>(null);
  const [task, setTask] = useState<TaskView | null>(null);
  const taskId = useRef<number | null>(null);

  const refresh = useCallback(async () => {
    const rep = await call(
      client.GET('/api/v1/jobs/{job_id}/report', { params: { path: { job_id: jobId }, query: { cells: false } } }),
    );
    if (isTask(rep)) {
      if (taskId.current !== rep.id) {
        taskId.current = rep.id;
        setTask(rep);
      }
      return;
    }
    if ('kind' in rep) return; // a sensor job: KindReport shows it
    taskId.current = null;
    setTask(null);
    setReport(rep);
  }, [jobId]);

  return { report, task, refresh };
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
