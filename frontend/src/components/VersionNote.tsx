import { useEffect, useState } from 'react';
import { call, client } from '../api/client';
import { ErrorBox } from './Status';

/** The note stored with a version (why it was made), editable afterwards. */
export function VersionNote(props: { rxId: number; version: number | null; note: string | undefined; onSaved: () => Promise<void> | void }) {
  const { rxId, version, note, onSaved } = props;
  const [editing, setEditing] = useState(false);
  const [text, setText] = useState('');
  const [error, setError] = useState<unknown>(null);
  useEffect(() => {
    setText(note ?? '');
    setEditing(false);
  }, [note, version]);
  if (version == null) return null;
  return (
    <div className="version-note" data-testid="rx-version-note">
      {!editing ? (
        <div className="small">
          <span className="muted">Note:</span> <span data-testid="rx-note-text">{note || '–'}</span>{' '}
          <button type="button" className="link" data-testid="rx-note-edit" onClick={() => setEditing(true)}>
            edit
          </button>
        </div>
      ) : (
        <form
          className="row"
          onSubmit={async (e) => {
            e.preventDefault();
            setError(null);
            try {
              await call(
                client.PATCH('/api/v1/prescriptions/{rx_id}/versions/{version}', { params: { path: { rx_id: rxId, version } }, body: { note: text } }),
              );
              await onSaved();
              setEditing(false);
            } catch (err) {
              setError(err);
            }
          }}
        >
          <input data-testid="rx-note-input" value={text} maxLength={2000} onChange={(e) => setText(e.target.value)} />
          <button data-testid="rx-note-save" data-write="">
            Save note
          </button>
        </form>
      )}
      <ErrorBox error={error} testid="rx-note-error" />
    </div>
  );
}
