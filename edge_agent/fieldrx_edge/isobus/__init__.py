"""ISOBUS (ISO 11783) for the edge agent: CAN transport on python-can, network management
(address claim, TP/BAM/ETP), the Task Controller server role and a rate-ECU client role.

See ``link``, ``transfers`` and ``network`` (ISO 11783-3/-5), ``ddop`` and
``process_data`` (ISO 11783-10), ``tc_server`` (with ``tc_client``, ``tc_mapping`` and
``implement``) and ``rate_ecu``. Nothing here imports the server package.
"""
