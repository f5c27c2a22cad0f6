//! Kubernetes as the batch engine: a manifest's tasks as an Indexed Job
//! (`completionMode: Indexed`), one pod per task (a flight, or a share of
//! a flight's detect). Kubernetes sets `JOB_COMPLETION_INDEX` in each pod,
//! and `postflight batch task` reads its task's index from it. postflight writes the Job; `kubectl apply`
//! submits it.

/// What the Job runs, and where.
#[derive(Debug, Clone)]
pub struct IndexedJob {
    /// The Job's name (a DNS label).
    pub name: String,
    /// A container image with `postflight` on its PATH.
    pub image: String,
    /// The manifest and fleet directory as the pods see them.
    pub manifest: String,
    pub fleet: String,
    /// The manifest's number of tasks: the Job's completions.
    pub tasks: usize,
    /// Pods at once.
    pub parallelism: usize,
    /// A PersistentVolumeClaim holding the flights and the fleet directory,
    /// mounted at `mount_path` (also the pods' working directory).
    pub volume_claim: Option<String>,
    pub mount_path: String,
    /// Each pod's CPU and memory request (and memory limit).
    pub cpu: String,
    pub memory: String,
    /// Options passed to every task's `postflight batch task`.
    pub task_args: Vec<String>,
}

impl IndexedJob {
    /// The Job as YAML, with comments saying what each part is for.
    pub fn yaml(&self) -> String {
        let q = |s: &str| serde_json::to_string(s).expect("a string");
        let mut command = vec![
            "postflight".to_string(),
            "batch".into(),
            "task".into(),
            self.manifest.clone(),
            "--out".into(),
            self.fleet.clone(),
        ];
        command.extend(self.task_args.iter().cloned());
        let command = command.iter().map(|c| q(c)).collect::<Vec<_>>().join(", ");
        let mut yaml = format!(
            "\
# postflight batch on Kubernetes: one pod per task of {manifest}.
# Written by `postflight batch k8s`; submit with `kubectl apply -f FILE`,
# follow with `postflight batch status {manifest} --out {fleet}`.
apiVersion: batch/v1
kind: Job
metadata:
  name: {name}
  labels:
    app.kubernetes.io/name: postflight-batch
spec:
  # Pod i runs task i of the manifest (from 0: a flight, or a share of a
  # flight's detect): Kubernetes sets JOB_COMPLETION_INDEX in the pod, and
  # `postflight batch task` reads it.
  completionMode: Indexed
  completions: {tasks}
  parallelism: {parallelism}
  # Each task is retried once on its own; a task that fails again is
  # recorded failed in its run directory while the others go on
  # (`postflight batch run --only-failed` runs it again later).
  backoffLimitPerIndex: 1
  template:
    metadata:
      labels:
        app.kubernetes.io/name: postflight-batch
    spec:
      restartPolicy: Never
      containers:
        - name: postflight
          image: {image}
          command: [{command}]
          workingDir: {mount}
          resources:
            # One flight's pipeline: its memory is bounded by the frames in
            # flight, not the recording's length.
            requests:
              cpu: {cpu}
              memory: {memory}
            limits:
              memory: {memory}
",
            manifest = self.manifest,
            fleet = self.fleet,
            name = q(&self.name),
            tasks = self.tasks,
            parallelism = self.parallelism.max(1),
            image = q(&self.image),
            mount = q(&self.mount_path),
            cpu = q(&self.cpu),
            memory = q(&self.memory),
        );
        if let Some(claim) = &self.volume_claim {
            yaml.push_str(&format!(
                "\
          # The flights, the manifest and the fleet directory.
          volumeMounts:
            - name: data
              mountPath: {mount}
      volumes:
        - name: data
          persistentVolumeClaim:
            claimName: {claim}
",
                mount = q(&self.mount_path),
                claim = q(claim),
            ));
        }
        yaml
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_yaml_ng::Value;

    fn job(claim: Option<&str>) -> IndexedJob {
        IndexedJob {
            name: "postflight-batch".into(),
            image: "registry.example/postflight:0.1".into(),
            manifest: "fleet: \"may\".toml".into(),
            fleet: "/data/out".into(),
            tasks: 12,
            parallelism: 3,
            volume_claim: claim.map(str::to_string),
            mount_path: "/data".into(),
            cpu: "2".into(),
            memory: "3Gi".into(),
            task_args: vec!["--quiet".into()],
        }
    }

    #[test]
    fn the_job_is_an_indexed_job_with_one_completion_per_task_running_it() {
        let doc: Value = serde_yaml_ng::from_str(&job(Some("flights")).yaml()).unwrap();
        assert_eq!(doc["apiVersion"], "batch/v1");
        assert_eq!(doc["kind"], "Job");
        let spec = &doc["spec"];
        assert_eq!(spec["completionMode"], "Indexed");
        assert_eq!(spec["completions"], 12);
        assert_eq!(spec["parallelism"], 3);
        let pod = &spec["template"]["spec"];
        assert_eq!(pod["restartPolicy"], "Never");
        let container = &pod["containers"][0];
        let command: Vec<&str> = container["command"]
            .as_sequence()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert_eq!(
            command,
            [
                "postflight",
                "batch",
                "task",
                "fleet: \"may\".toml",
                "--out",
                "/data/out",
                "--quiet"
            ]
        );
        assert_eq!(container["volumeMounts"][0]["mountPath"], "/data");
        assert_eq!(
            pod["volumes"][0]["persistentVolumeClaim"]["claimName"],
            "flights"
        );
        assert_eq!(container["resources"]["limits"]["memory"], "3Gi");
    }

    #[test]
    fn without_a_volume_claim_the_job_mounts_nothing() {
        let doc: Value = serde_yaml_ng::from_str(&job(None).yaml()).unwrap();
        let pod = &doc["spec"]["template"]["spec"];
        assert!(pod.get("volumes").is_none());
        assert!(pod["containers"][0].get("volumeMounts").is_none());
    }
}
