import { call, client, errorText, setSession, type SessionInfo } from '../api/client';

/**
 * Organisation name, or a switcher when the user belongs to several. Switching
 * asks the server for a token scoped to the chosen organisation.
 */
export function OrgSwitcher({ session, onChange }: { session: SessionInfo; onChange: (s: SessionInfo) => void }) {
  const orgs = session.organisations ?? [];
  const role = session.organisation?.role;
  if (orgs.length < 2)
    return (
      <span data-testid="org-name">
        {session.organisation?.name ?? ''}
        {role ? <span className="role"> · {role}</span> : null}
      </span>
    );
  return (
    <select
      data-testid="org-switcher"
      value={session.organisation?.id ?? ''}
      onChange={async (e) => {
        const id = Number(e.target.value);
        try {
          const r = await call(client.POST('/api/v1/auth/switch', { body: { organisation_id: id } }));
          const info = { user: r.user, organisation: r.organisation, organisations: r.organisations };
          setSession(r.access_token, info);
          onChange(info);
          location.reload();
        } catch (err) {
          alert(errorText(err));
        }
      }}
    >
      {orgs.map((o) => (
        <option key={o.id} value={o.id}>
          {o.name}
        </option>
      ))}
    </select>
  );
}
