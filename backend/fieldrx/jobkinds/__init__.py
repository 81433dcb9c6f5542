"""The server's side of the job kinds: what only the server does for a kind (its report's
figures, live alerts, job-creation checks), registered per kind name. The kinds themselves
(name, settings, what the machine needs) are ``fieldrx_edge.jobkinds.registry``'s."""
