"""FieldRx's TC and rate ECU over ``--can socketcand:...`` through a local socketcand hub
process (``socketcand_hub``): the transport the peer test used, with TCP_NODELAY."""

from __future__ import annotations

import time

import pytest
from fieldrx_edge.isobus import process_data as pdm
from fieldrx_edge.isobus.network import Node
from fieldrx_edge.isobus.pair import ecu_name, tc_name
from fieldrx_edge.isobus.rate_ecu import RateEcu
from fieldrx_edge.isobus.tc_server import TaskControllerServer
from fieldrx_edge.isobus.transport import open_bus
from fieldrx_edge.metering import calibration_from_dict

from tests.edge.jobfactory import trial_plot
from tests.edge.socketcand_hub import start_hub_process


@pytest.fixture
def hub_port():
    proc, port = start_hub_process()
    yield port
    proc.terminate()
    proc.wait(timeout=10)


def test_tc_drives_the_rate_ecu_over_socketcand(hub_port):
    job = trial_plot()
    spec = f"socketcand:127.0.0.1:{hub_port}:can0"
    tc_node = Node(open_bus(spec), tc_name(), 0xF7, label="tc")
    ecu_node = Node(open_bus(spec), ecu_name(), 0x80, label="ecu")
    try:
        tc = TaskControllerServer(tc_node, implement_width_m=job.implement_width_m)
        ecu = RateEcu(ecu_node, calibration_from_dict(job.calibration), job.implement_width_m)
        tc_node.start()
        ecu_node.start()
        deadline = time.monotonic() + 60.0  # readiness-based: the machine may be loaded
        while time.monotonic() < deadline and not (ecu.connected and tc.client):
            tc_node.poll(0.005)
            tc.update()
            ecu_node.poll(0.005)
            ecu.update()
        assert ecu.connected and tc.client is not None
        # the peers learnt each other's NAME through the hub
        assert tc_node.peers.get(ecu_node.address) == ecu_node.name
        while time.monotonic() < deadline and ecu.rate_mg_m2 != 70_000:
            tc.command(700.0, True, 2.0)
            for _ in range(5):
                ecu_node.poll(0.005)
                tc_node.poll(0.0)
                tc.update()
                ecu.update()
        assert ecu.rate_mg_m2 == 70_000 and ecu.sections() == [True]
        assert ecu.rate_kg_ha() == 700.0 and pdm.MG_M2_PER_KG_HA == 100.0
    finally:
        tc_node.close()
        ecu_node.close()
