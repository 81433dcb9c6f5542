"""The job kinds, one module each; every module here registers its kind with
``fieldrx_edge.jobkinds.registry`` when imported (the registry imports them all)."""
