import { useEffect, useState } from 'react';
import { useQueryClient } from '@tanstack/react-query';
import { client, getSession, getToken, setSession, type SessionInfo } from './api/client';
import { navigate, useRoute } from './router';
import { Login } from './screens/Login';
import { FieldsScreen } from './screens/Fields';
import { FieldEditor } from './screens/FieldEditor';
import { FieldDetail } from './screens/FieldDetail';
import { PlanScreen } from './screens/Plan';
import { PrescriptionScreen } from './screens/Prescription';
import { JobsScreen } from './screens/Jobs';
import { JobReport } from './screens/JobReport';
import { FleetScreen } from './screens/Fleet';
import { MachineDetail } from './screens/MachineDetail';
import { MachinesScreen } from './screens/Machines';
import { SettingsScreen } from './screens/Settings';
import { OrgSwitcher } from './components/OrgSwitcher';

export function App() {
  const route = useRoute();
  const [session, setSess] = useState<SessionInfo | null>(getToken() ? getSession() : null);
  const queryClient = useQueryClient();

  useEffect(() => {
    // another user's (or no user's) data must not be served from the cache
    const out = () => {
      queryClient.clear();
      setSess(null);
    };
    window.addEventListener('fieldrx:logout', out);
    return () => window.removeEventListener('fieldrx:logout', out);
  }, [queryClient]);

  if (!session || !getToken()) {
    return (
      <Login
        onLogin={(s) => {
          setSess(s);
          if (route[0] === 'login' || route.length === 0) navigate('/fields');
        }}
      />
    );
  }

  const [a, b, c] = route;
  const id = b ? Number(b) : NaN;
  let screen: React.ReactNode;
  if (a === 'fields' && b === 'new') screen = <FieldEditor />;
  else if (a === 'fields' && c === 'edit') screen = <FieldEditor fieldId={id} />;
  else if (a === 'fields' && b) screen = <FieldDetail fieldId={id} />;
  else if (a === 'plans' && b) screen = <PlanScreen planId={id} />;
  else if (a === 'prescriptions' && b) screen = <PrescriptionScreen rxId={id} />;
  else if (a === 'jobs' && b) screen = <JobReport jobId={id} />;
  else if (a === 'jobs') screen = <JobsScreen />;
  else if (a === 'fleet') screen = <FleetScreen />;
  else if (a === 'machines' && b) screen = <MachineDetail machineId={id} />;
  else if (a === 'machines') screen = <MachinesScreen />;
  else if (a === 'settings') screen = <SettingsScreen />;
  else screen = <FieldsScreen />;

  const nav = (p: string, label: string, tid: string) => (
    <a href={`#/${p}`} className={a === p || (!a && p === 'fields') ? 'active' : ''} data-testid={tid}>
      {label}
    </a>
  );
  return (
    <div className={`app ${(session.organisation as { role?: string } | undefined)?.role === 'viewer' ? 'role-viewer' : ''}`}>
      <header className="topbar">
        <span className="brand">FieldRx</span>
        <nav>
          {nav('fields', 'Fields', 'nav-fields')}
          {nav('jobs', 'Jobs', 'nav-jobs')}
          {nav('fleet', 'Fleet', 'nav-fleet')}
          {nav('machines', 'Machines', 'nav-machines')}
          {nav('settings', 'Settings', 'nav-settings')}
        </nav>
        <span className="spacer" />
        <OrgSwitcher session={session} onChange={setSess} />
        <span className="user" data-testid="current-user">
          {session.user?.email ?? ''}
        </span>
        <button
          data-testid="logout"
          onClick={() => {
            // Revoke the token on the server too; sign out locally whatever happens.
            void client.POST('/api/v1/auth/logout').catch(() => undefined);
            setSession(null);
            queryClient.clear();
            setSess(null);
          }}
        >
          Sign out
        </button>
      </header>
      <main className="content">{screen}</main>
    </div>
  );
}
