// Reads a TASKDATA zip with isoxml-js (npm "isoxml", dev4Agriculture) and prints what it
// found as one JSON object: the parser's warnings, the first task's type-2 grid as cell
// centres with their value, and every treatment zone with its code, first process data
// value and polygons as GeoJSON. Used by tests/formats/test_isoxml_js.py.
// Usage: node read_taskdata.js TASKDATA.zip
"use strict";
const fs = require("fs");
const { ISOXMLManager, ExtendedPolygon } = require("isoxml");

async function main() {
  const data = new Uint8Array(fs.readFileSync(process.argv[2]));
  const manager = new ISOXMLManager();
  await manager.parseISOXMLFile(data, "application/zip");
  const task = manager.rootElement.attributes.Task[0];
  const out = { warnings: manager.getWarnings(), grid: null, zones: [] };
  const grid = (task.attributes.Grid || [])[0];
  if (grid) {
    const a = grid.attributes;
    const fc = task.getGridAsGeoJSON(["value"]);
    out.grid = {
      rows: a.GridMaximumRow,
      cols: a.GridMaximumColumn,
      cell_east: a.GridCellEastSize,
      cell_north: a.GridCellNorthSize,
      cells: fc.features.map((f) => {
        const r = f.geometry.coordinates[0];
        return [(r[0][0] + r[2][0]) / 2, (r[0][1] + r[2][1]) / 2, f.properties.value];
      }),
    };
  }
  for (const tzn of task.attributes.TreatmentZone || []) {
    const pdv = (tzn.attributes.ProcessDataVariable || [])[0];
    const polys = tzn.attributes.PolygonTreatmentZoneonly || [];
    out.zones.push({
      code: tzn.attributes.TreatmentZoneCode,
      value: pdv ? pdv.attributes.ProcessDataValue : null,
      ddi: pdv ? pdv.attributes.ProcessDataDDI : null,
      geometry: polys.length ? ExtendedPolygon.toGeoJSON(polys) : null,
    });
  }
  process.stdout.write(JSON.stringify(out));
}

main().catch((e) => {
  process.stderr.write(String(e && e.stack ? e.stack : e) + "\n");
  process.exit(1);
});
