import { useEffect, useState } from 'react';
import { call, client, errorText } from '../api/client';
import { isFinal, pollTask, progressLabel, type TaskView } from '../lib/tasks';

/**
 * Progress of a background task (GET /api/v1/tasks/{id}, polled): a bar, the stage, a Cancel
 * button while it runs, and ``onDone`` once it ends (with the final view, whatever the end).
 */
export function TaskProgress(props: { task: TaskView; onDone?: (t: TaskView) => void; label?: string }) {
  const { task, onDone, label } = props;
  const [view, setView] = useState<TaskView>(task);
  const [err, setErr] = useState('');

  useEffect(() => {
    const signal = { aborted: false };
    pollTask(
      () => call(client.GET('/api/v1/tasks/{task_id}', { params: { path: { task_id: task.id } } })),
      task.url,
      { signal, onUpdate: setView })
      .then((t) => {
        if (!signal.aborted && isFinal(t)) onDone?.(t);
      })
      .catch((e) => setErr(errorText(e)));
    return () => {
      signal.aborted = true;
    };
    // one poll per task; onDone is read when it ends
  }, [task.url]);

  const cancel = async () => {
    try {
      setView(await call(client.POST('/api/v1/tasks/{task_id}/cancel', { params: { path: { task_id: task.id } } })));
    } catch (e) {
      setErr(errorText(e));
    }
  };

  const done = isFinal(view);
  return (
    <div className="task-progress" data-testid="task-progress" data-status={view.status}>
      {label && <span className="muted">{label} </span>}
      <progress max={1} value={view.status === 'queued' ? undefined : view.progress} data-testid="task-bar" />
      <span data-testid="task-label" className={view.status === 'failed' ? 'error' : undefined}>
        {' '}
        {progressLabel(view)}
        {view.counts ? ` (${view.counts.succeeded ?? 0} done, ${view.counts.failed ?? 0} failed)` : ''}
      </span>
      {!done && !view.cancel_requested && (
        <button type="button" className="small" data-write="" data-testid="task-cancel" onClick={() => void cancel()}>
          Cancel
        </button>
      )}
      {err && <span className="error"> {err}</span>}
    </div>
  );
}
