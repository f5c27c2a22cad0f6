//! The flight's topics, and the topic settings checked against them.

use std::collections::BTreeMap;

use postflight_core::Key;
use postflight_core::outputs::ingest::TopicSummary;

use crate::error::IngestError;
use crate::ingested::Ingested;
use crate::ros::schema;
use crate::settings::keys;
use crate::stage::IngestOptions;

/// Messages per topic, over every recording.
pub(crate) fn every_topic(ingested: &[Ingested]) -> BTreeMap<String, TopicSummary> {
    let mut all = BTreeMap::new();
    for one in ingested {
        let topics = one.summary.messages.iter();
        all.extend(topics.map(|(t, s)| (t.clone(), s.clone())));
    }
    all
}

pub(crate) fn check_topic_flags(
    options: &IngestOptions,
    topics: &BTreeMap<String, TopicSummary>,
) -> Result<(), IngestError> {
    let available = || topics.keys().cloned().collect::<Vec<_>>().join(", ");
    let check = |key: Key, topic: &String, expected: &[&str]| -> Result<(), IngestError> {
        let Some(TopicSummary { schema, .. }) = topics.get(topic) else {
            return Err(IngestError::TopicNotFound {
                key,
                topic: topic.clone(),
                available: available(),
            });
        };
        if !expected.contains(&schema::ros2_name(schema).as_ref()) {
            return Err(IngestError::TopicSchema {
                key,
                topic: topic.clone(),
                schema: schema.clone(),
                expected: expected.join(" or "),
            });
        }
        Ok(())
    };
    for t in &options.settings.image_topics {
        check(
            keys::image_topics,
            t,
            &[schema::IMAGE, schema::COMPRESSED_IMAGE],
        )?;
    }
    if let Some(t) = &options.settings.pose_topic {
        check(
            keys::pose_topic,
            t,
            &[
                schema::POSE_STAMPED,
                schema::POSE_WITH_COVARIANCE_STAMPED,
                schema::ODOMETRY,
            ],
        )?;
    }
    if let Some(t) = &options.settings.camera_info_topic {
        check(keys::camera_info_topic, t, &[schema::CAMERA_INFO])?;
    }
    if let Some(t) = &options.settings.map_topic {
        check(keys::map_topic, t, &[schema::POINT_CLOUD2])?;
    }
    Ok(())
}
