"""Telemetry uplink: durable local queue, HTTP and MQTT senders."""

from fieldrx_edge.uplink.backoff import Backoff
from fieldrx_edge.uplink.http import HttpSender
from fieldrx_edge.uplink.mqtt import MqttBroker, MqttSender
from fieldrx_edge.uplink.queue import TelemetryQueue

__all__ = ["Backoff", "HttpSender", "MqttBroker", "MqttSender", "TelemetryQueue"]
