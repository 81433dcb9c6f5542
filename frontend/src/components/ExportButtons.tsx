import { useState } from 'react';
import { download, downloadOrTask, errorText, type Schemas } from '../api/client';
import { TaskProgress } from './TaskProgress';

export interface ExportFormat {
  format: string;
  label: string;
  /** file name used when the server names none */
  fallback: string;
}

/**
 * Export buttons for a route that answers a file, or (a large job) 202 with an ``export``
 * task: then the task's progress is shown and the file is saved once it is written
 * (``GET /tasks/{id}/download``). Screen-only (hidden when printed).
 */
export function ExportButtons({ path, formats }: { path: string; formats: ExportFormat[] }) {
  const [task, setTask] = useState<Schemas['TaskOut'] | null>(null);
  const [busy, setBusy] = useState('');
  const [note, setNote] = useState('');
  const [error, setError] = useState('');

  const start = async (f: ExportFormat) => {
    setBusy(f.format);
    setNote('');
    setError('');
    try {
      const sep = path.includes('?') ? '&' : '?';
      const got = await downloadOrTask(`${path}${sep}format=${encodeURIComponent(f.format)}`, f.fallback);
      if ('task' in got) setTask(got.task);
      else setNote(`Saved ${got.file}`);
    } catch (e) {
      setError(errorText(e));
    } finally {
      setBusy('');
    }
  };

  const finished = async (t: { status: string; result_url?: string | null; result?: Record<string, unknown> | null }) => {
    setTask(null);
    if (t.status !== 'succeeded' || !t.result_url) return;
    try {
      setNote(`Saved ${await download(t.result_url, String(t.result?.filename ?? 'export'))}`);
    } catch (e) {
      setError(errorText(e));
    }
  };

  return (
    <div className="export-buttons screen-only" data-testid="export-buttons">
      <span className="muted small">Export: </span>
      {formats.map((f) => (
        <button
          key={f.format}
          type="button"
          data-testid={`export-${f.format}`}
          disabled={Boolean(busy) || task != null}
          onClick={() => void start(f)}
        >
          {busy === f.format ? `${f.label}…` : f.label}
        </button>
      ))}
      {task && <TaskProgress key={task.id} task={task} label="Writing the file" onDone={(t) => void finished(t)} />}
      {note && (
        <p className="ok small" data-testid="export-note">
          {note}
        </p>
      )}
      {error && (
        <p className="error small" role="alert" data-testid="export-error">
          {error}
        </p>
      )}
    </div>
  );
}
