import { useState } from 'react';
import { basemapUrl, setBasemapUrl } from '../map/setup';

export function SettingsScreen() {
  const [url, setUrl] = useState(basemapUrl());
  const [saved, setSaved] = useState(false);
  return (
    <div className="page">
      <h2>Settings</h2>
      <form
        className="form"
        onSubmit={(e) => {
          e.preventDefault();
          setBasemapUrl(url.trim());
          setSaved(true);
        }}
      >
        <label>
          Base map XYZ tile URL (blank: plain background, works offline)
          <input
            data-testid="basemap-url"
            placeholder="https://tile.example.org/{z}/{x}/{y}.png"
            value={url}
            onChange={(e) => {
              setUrl(e.target.value);
              setSaved(false);
            }}
          />
        </label>
        <button data-testid="basemap-save">Save</button>
        {saved && <p className="ok">Saved: maps use it from the next screen you open.</p>}
      </form>
    </div>
  );
}
