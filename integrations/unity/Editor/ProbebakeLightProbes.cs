// Loads a `probebake export VOLUME --format unity -o probes.json` file into the open scene's light
// probes (docs/engines.md, "Unity"). Put this file in an Editor folder of a Unity project, then
// Tools > probebake > Import light probes...
//
// What it does:
//  1. creates (or reuses) a GameObject "probebake light probes" at the origin with a
//     LightProbeGroup whose probePositions are the exported positions (Unity's frame already);
//  2. runs Lightmapping.Bake() so Unity builds its LightProbes (the tetrahedralisation; the
//     scene's lighting settings apply, so turn off baked lightmaps you do not want);
//  3. overwrites LightmapSettings.lightProbes.bakedProbes with the exported coefficients, matching
//     Unity's probe order to the file's by position (Unity may reorder and merges duplicates).
// The file's "sh" is SphericalHarmonicsL2[channel, i] at index 9 * channel + i: radiance
// coefficients in Unity's basis and frame, so ShadeSH9 gives irradiance / pi.
// Probes of other groups in the scene keep what the bake gave them.
using System;
using System.Collections.Generic;
using System.IO;
using UnityEditor;
using UnityEditor.SceneManagement;
using UnityEngine;
using UnityEngine.Rendering;

public static class ProbebakeLightProbes
{
    [Serializable]
    class Probe
    {
        public float[] position;
        public float[] sh;
    }

    [Serializable]
    class ProbeFile
    {
        public string frame;
        public string sh_convention;
        public Probe[] probes;
    }

    const string GroupName = "probebake light probes";

    [MenuItem("Tools/probebake/Import light probes...")]
    static void ImportMenu()
    {
        string path = EditorUtility.OpenFilePanel("probebake export (--format unity)", "", "json");
        if (!string.IsNullOrEmpty(path)) Import(path);
    }

    // Imports `path`; throws with the field named when the file is not a probebake Unity export.
    public static void Import(string path)
    {
        ProbeFile file = JsonUtility.FromJson<ProbeFile>(File.ReadAllText(path));
        if (file == null || file.probes == null || file.probes.Length == 0)
            throw new InvalidDataException(path + ": probes: missing or empty");
        var positions = new Vector3[file.probes.Length];
        var coefficients = new Dictionary<Vector3, SphericalHarmonicsL2>();
        for (int p = 0; p < file.probes.Length; ++p)
        {
            Probe probe = file.probes[p];
            if (probe.position == null || probe.position.Length != 3)
                throw new InvalidDataException(path + ": probes[" + p + "].position: want 3 numbers");
            if (probe.sh == null || probe.sh.Length != 27)
                throw new InvalidDataException(path + ": probes[" + p + "].sh: want 27 numbers");
            positions[p] = new Vector3(probe.position[0], probe.position[1], probe.position[2]);
            var sh = new SphericalHarmonicsL2();
            for (int channel = 0; channel < 3; ++channel)
                for (int i = 0; i < 9; ++i) sh[channel, i] = probe.sh[9 * channel + i];
            coefficients[positions[p]] = sh;
        }

        // Explicit null tests: Unity objects compare equal to null when destroyed, `??` does not see it.
        GameObject go = GameObject.Find(GroupName);
        if (go == null) go = new GameObject(GroupName);
        go.transform.SetPositionAndRotation(Vector3.zero, Quaternion.identity);
        go.transform.localScale = Vector3.one;
        LightProbeGroup group = go.GetComponent<LightProbeGroup>();
        if (group == null) group = go.AddComponent<LightProbeGroup>();
        group.probePositions = positions;

        if (!Lightmapping.Bake())
            throw new InvalidOperationException("Lightmapping.Bake failed: Unity built no light probes");
        LightProbes lightProbes = LightmapSettings.lightProbes;
        if (lightProbes == null)
            throw new InvalidOperationException("the bake left LightmapSettings.lightProbes empty (is Baked GI on?)");
        Vector3[] bakedPositions = lightProbes.positions;
        SphericalHarmonicsL2[] baked = lightProbes.bakedProbes;
        int matched = 0;
        for (int i = 0; i < bakedPositions.Length; ++i)
        {
            if (coefficients.TryGetValue(bakedPositions[i], out SphericalHarmonicsL2 sh)) { baked[i] = sh; ++matched; continue; }
            // Positions round-trip exactly in practice; fall back to the nearest within 1 mm.
            float best = 1e-3f;
            foreach (var entry in coefficients)
            {
                float d = Vector3.Distance(entry.Key, bakedPositions[i]);
                if (d < best) { best = d; baked[i] = entry.Value; }
            }
            if (best < 1e-3f) ++matched;
        }
        lightProbes.bakedProbes = baked;
        EditorUtility.SetDirty(lightProbes);
        EditorSceneManager.MarkSceneDirty(go.scene);
        Debug.Log("probebake: " + matched + " of " + bakedPositions.Length + " light probes set from " + path
                  + " (" + file.probes.Length + " in the file)");
    }
}
